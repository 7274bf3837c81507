"""Where the files a robot description names are: ``package://`` URIs and relative paths.

A URDF (or SDF, MJCF) names its meshes ``package://<package>/<path>``, ``file://<path>``, an
absolute path or a path relative to the file. :class:`PackageResolver` turns each into a file:

1. ``package_paths`` given by the user: package name → its folder;
2. every ``package.xml`` found in the description's folder or above it: the folder is the package
   named by its ``<name>`` element, and also by the folder's own name (example-robot-data's
   ``package.xml`` says ``example_robot_descriptions``, its URDFs say ``example-robot-data``);
3. a folder named like the package, above the description or beside one of its parents (the ROS
   layout ``<ws>/src/<package>/urdf/robot.urdf`` without a ``package.xml``).

An unknown package raises :class:`~sotdrake.exceptions.PackageNotFound` listing the packages found
and how to give one (``package_paths={'name': '/path/to/name'}``). A URDF's URIs are resolved here
one by one (:meth:`PackageResolver.path`); for an SDF or MJCF file, which Drake's parser reads
itself, :meth:`PackageResolver.packages_in` gives the folders of the packages its text names, by
the same rules, for the parser's package map.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Container, Mapping
from os import PathLike
from pathlib import Path

from ..exceptions import InvalidInput, PackageNotFound, RobotDescriptionError

_PACKAGE_URI = re.compile(r"^package:/{2,3}([^/]+)/(.*)$")
_PACKAGE_IN_TEXT = re.compile(r"""package://([^/\s"'<>]+)/[^\s"'<>]*""")


def _package_name(package_xml: Path) -> str | None:
    try:
        element = ET.parse(package_xml).getroot().find("name")
    except (ET.ParseError, OSError):
        return None
    return None if element is None or not element.text else element.text.strip()


def detect_packages(start: Path) -> dict[str, Path]:
    """Packages declared by a ``package.xml`` in ``start`` or one of its parents, nearest first
    (a nearer package shadows a farther one of the same name)."""
    found: dict[str, Path] = {}
    for folder in [start, *start.parents]:
        package_xml = folder / "package.xml"
        if package_xml.is_file():
            for name in (_package_name(package_xml), folder.name):
                if name and name not in found:
                    found[name] = folder
    return found


class PackageResolver:
    """Resolves the file names of one robot description (see the module docstring)."""

    def __init__(self, description: Path, package_paths: Mapping[str, str | PathLike[str]] | None = None):
        self.folder = description.resolve().parent
        self.packages: dict[str, Path] = {}
        if package_paths is not None:
            if not isinstance(package_paths, Mapping):
                raise InvalidInput(f"package_paths: expected a dict of package name → folder, got {package_paths!r:.100}")
            for name, folder in package_paths.items():
                if not isinstance(name, str) or not isinstance(folder, (str, PathLike)):
                    raise InvalidInput(f"package_paths: expected package names → folders (strings or paths), got "
                                       f"{name!r:.60}: {folder!r:.60}")
                path = Path(folder).expanduser()
                if not path.is_dir():
                    raise InvalidInput(f"package_paths[{name!r}]: {str(path)!r} is not a folder")
                self.packages[str(name)] = path.resolve()
        for name, folder in detect_packages(self.folder).items():
            self.packages.setdefault(name, folder)

    def package(self, name: str, uri: str) -> Path:
        """The folder of package ``name`` (``uri``: the URI being resolved, for the message)."""
        if name in self.packages:
            return self.packages[name]
        for folder in [self.folder, *self.folder.parents]:
            if folder.name == name:
                return folder
            if (folder / name).is_dir():
                return folder / name
        raise PackageNotFound(name, list(self.packages), uri)

    def packages_in(self, text: str, known: Container[str] = ()) -> dict[str, Path]:
        """The folder of each package a ``package://<name>/…`` URI of ``text`` names (but those in
        ``known``), found by the rules of the module docstring; :class:`PackageNotFound` for one
        that is not found."""
        found: dict[str, Path] = {}
        for match in _PACKAGE_IN_TEXT.finditer(text):
            name = match.group(1)
            if name not in found and name not in known:
                found[name] = self.package(name, match.group(0))
        return found

    def path(self, uri: str) -> Path:
        """The file ``uri`` names; :class:`RobotDescriptionError` if it does not exist."""
        match = _PACKAGE_URI.match(uri)
        if match:
            path = self.package(match.group(1), uri) / match.group(2)
        elif uri.startswith("file://"):
            path = Path(uri[len("file://") :])
        else:
            path = Path(uri)
            if not path.is_absolute():
                path = self.folder / path
        if not path.is_file():
            raise RobotDescriptionError(f"the file {uri!r} named by the robot description is not at {path}")
        return path
