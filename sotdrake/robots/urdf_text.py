"""The URDF text fix-ups Drake needs, in one function: :func:`prepare_urdf`.

example-robot-data's URDFs are written for ROS and Pinocchio. Before Drake parses one, its text is
changed as follows (nothing else is touched, so kinematics and inertias stay those of the file):

* mesh URIs are resolved to files: ``package://example-robot-data/robots/…``, the three-slash
  ``package:///example-robot-data/…`` and the ROS form ``package://<name>_description/…`` (a
  package under ``robots/``). STL and COLLADA (``.dae``) meshes are replaced by cached OBJ
  conversions (:mod:`.mesh_cache`); without meshes every ``<visual>``/``<collision>`` is dropped
  (control models need no geometry);
* ``<mimic>`` on fixed (0-DOF) joints is removed (Drake rejects it; a fixed joint has nothing to
  mimic);
* the ``friction`` attribute of ``<dynamics>`` is removed (``MultibodyPlant`` has no joint friction);
* transmissions Drake cannot use are removed: anything but a ``SimpleTransmission``, and ones naming
  a joint the file does not have or a fixed joint (the loader then gives every 1-DOF joint left
  without an actuator one of its own, see :func:`sotdrake.robots.loader.add_actuators`);
* what Drake would ignore with a warning is removed: ``<gazebo>`` blocks (simulator plugins), the
  joints' ``<safety_controller>`` and ``<calibration>`` (ROS controller settings), the transmissions'
  ``<mechanicalReduction>`` (``MultibodyPlant`` has no gear ratio: a command is a joint torque)
  and the ``type`` attribute of ``<link>``;
* a named ``<material>`` defined more than once is defined once (Drake refuses a second definition):
  a top-level definition is the model's, as ROS' URDF parser reads it, and a definition of that name
  inside a ``<visual>`` becomes a reference to it (TALOS' ``full_v2`` defines ``DarkGrey`` at the top
  level and again, lighter, in a visual); a top-level definition repeated identically is dropped, and
  one inside a visual repeating an earlier one becomes a reference. Two different top-level
  definitions, or two different ones in visuals with none at the top level (which Drake refuses
  too), are refused (:class:`~sotdrake.exceptions.RobotDescriptionError` naming the material).

This is the one place where URDF text is changed: further checks on the text go here.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr, unescape

from ..exceptions import RobotDescriptionError, SotError
from .mesh_cache import obj_for_mesh
from .urdf_checks import check_urdf_limits

#: Mesh formats converted to OBJ (Drake's Meshcat and proximity geometry want OBJ or glTF).
CONVERTED_MESH_SUFFIXES = (".stl", ".dae")

_MESH_URI = re.compile(r"""(<mesh\b[^>]*?\bfilename\s*=\s*)(["'])(.*?)\2""", re.S)


def _element(tag: str) -> str:
    """A regular expression of one ``<tag …/>`` or ``<tag …>…</tag>`` element (not nested in itself)."""
    return rf"<{tag}\b[^>]*/>|<{tag}\b(?:[^>]*[^/>])?>.*?</{tag}>"


def resolve_mesh_path(uri: str, share: Path) -> Path:
    """The file a mesh URI of an example-robot-data URDF names (``share``: ``share/example-robot-data``)."""
    if uri.startswith("file://"):
        path = Path(uri[len("file://") :])
    elif re.match(r"^package:/{2,3}example-robot-data/", uri):
        path = share / re.sub(r"^package:/{2,3}example-robot-data/", "", uri)
    elif uri.startswith("package://"):
        path = share / "robots" / uri[len("package://") :]
    else:
        path = Path(uri)
    if not path.is_file():
        raise SotError(f"mesh {uri} not found at {path}")
    return path


def _mesh_uri(uri: str, share: Path, resolve: Callable[[str], Path] | None = None) -> str:
    path = resolve_mesh_path(uri, share) if resolve is None else resolve(uri)
    if path.suffix.lower() in CONVERTED_MESH_SUFFIXES:
        path = obj_for_mesh(path)
    # file:// and the path as it is (Drake does not decode a URI's %-escapes), escaped for the attribute.
    return escape("file://" + str(path.resolve()), {'"': "&quot;", "'": "&apos;"})


def prepare_urdf(
    text: str,
    share: Path,
    meshes: bool,
    collision: bool = True,
    source: str = "URDF",
    resolve: Callable[[str], Path] | None = None,
) -> str:
    """``text`` with the fix-ups of the module docstring applied, after its joint limits are checked
    (:func:`~sotdrake.robots.urdf_checks.check_urdf_limits`: Drake would abort the process on them).

    ``meshes``: keep visual and collision geometry (resolved, converted); otherwise drop it.
    ``collision``: with meshes, keep the ``<collision>`` elements too (a physics model may add its
    own contact geometry instead). ``share`` is example-robot-data's ``share/example-robot-data``;
    ``source`` names the file in error messages; ``resolve`` (a mesh URI → its file, e.g.
    :meth:`sotdrake.robots.packages.PackageResolver.path`) replaces :func:`resolve_mesh_path`.
    """
    check_urdf_limits(text, source)  # before any parser sees it

    def fix_joint(match: re.Match) -> str:
        joint = match.group(0)
        opening = re.match(r"<joint\b[^>]*>", joint)
        if opening and re.search(r"""\stype\s*=\s*(["'])fixed\1""", opening.group(0)):
            joint = re.sub(r"<mimic\b[^>]*?(/>|>.*?</mimic\s*>)", "", joint, flags=re.S)
        return joint

    text = re.sub(r"<!--.*?-->", "", text, flags=re.S)  # (a tag named in a comment is not one)
    for tag in ("gazebo", "safety_controller", "calibration", "mechanicalReduction"):
        text = re.sub(_element(tag), "", text, flags=re.S)
    text = re.sub(r"""(<link\b[^>]*?)\stype\s*=\s*("[^"]*"|'[^']*')""", r"\1", text)
    text = re.sub(_element("joint"), fix_joint, text, flags=re.S)
    text = re.sub(r"""\sfriction\s*=\s*("[^"]*"|'[^']*')""", "", text)
    root = ET.fromstring(text)
    moving = {j.get("name") for j in root.findall("joint") if j.get("type") != "fixed"}

    def keep_transmission(match: re.Match) -> str:
        block = match.group(0)
        names = [m[1] for m in re.findall(r"""<joint\b[^>]*\bname\s*=\s*(["'])(.+?)\1""", block)]
        simple = "SimpleTransmission" in block and all(n in moving for n in names)
        return block if simple else ""

    text = re.sub(_element("transmission"), keep_transmission, text, flags=re.S)
    text = merge_materials(text, source)
    if not meshes:
        return re.sub(_element("visual") + "|" + _element("collision"), "", text, flags=re.S)
    if not collision:
        text = re.sub(_element("collision"), "", text, flags=re.S)
    return _MESH_URI.sub(lambda m: m.group(1) + m.group(2) + _mesh_uri(unescape(m.group(3)), share, resolve) + m.group(2), text)


def _material_definition(element: ET.Element) -> tuple | None:
    """What a ``<material>`` element defines (its colour and texture, numbers compared as numbers), or
    None when it only names a material (a reference)."""
    parts: list[tuple] = []
    for child in element:
        value: object = tuple(sorted(child.attrib.items()))
        if child.tag == "color":
            try:
                value = tuple(float(word) for word in (child.get("rgba") or "").split())
            except ValueError:
                pass
        parts.append((child.tag, value))
    return tuple(sorted(parts, key=repr)) or None


def _describe(definition: tuple) -> str:
    return ", ".join(f"{tag} {' '.join(map(str, value)) if tag == 'color' else value}" for tag, value in definition)


def _named_definition(block: str) -> tuple[str | None, tuple | None]:
    """The name and definition (:func:`_material_definition`) of one ``<material>`` element's text."""
    try:
        element = ET.fromstring(block)
    except ET.ParseError:  # (a prefix declared on <robot> only: left to Drake's parser)
        return None, None
    return element.get("name"), _material_definition(element)


def merge_materials(text: str, source: str = "URDF") -> str:
    """``text`` with every named ``<material>`` defined once (see the module docstring); two different
    definitions the rule does not settle raise :class:`RobotDescriptionError` naming the material."""
    top: dict[str, tuple] = {}
    for element in ET.fromstring(text).findall("material"):
        name, definition = element.get("name"), _material_definition(element)
        if name is None or definition is None:
            continue
        if top.setdefault(name, definition) != definition:
            raise RobotDescriptionError(f"{source}: material {name!r} is defined twice at the top level, differently: "
                                        f"{_describe(top[name])} and {_describe(definition)}")
    in_visuals: dict[str, tuple] = {}
    written: set[str] = set()

    def in_visual(match: re.Match) -> str:
        name, definition = _named_definition(match.group(0))
        if name is None or definition is None:
            return match.group(0)
        if name not in top and name not in in_visuals:
            in_visuals[name] = definition
            return match.group(0)
        if name not in top and in_visuals[name] != definition:
            raise RobotDescriptionError(f"{source}: material {name!r} is defined twice in visuals, differently: "
                                        f"{_describe(in_visuals[name])} and {_describe(definition)}")
        return f"<material name={quoteattr(name)}/>"  # (the top level's definition, or the same as before)

    def merge(match: re.Match) -> str:
        block = match.group(0)
        if block.startswith("<visual"):
            return re.sub(_element("material"), in_visual, block, flags=re.S)
        name, definition = _named_definition(block)
        if name is None or name not in top or definition is None:
            return block
        if name in written:  # (repeated identically: a different one was refused above)
            return ""
        written.add(name)
        return block

    return re.sub(_element("visual") + "|" + _element("material"), merge, text, flags=re.S)
