"""Checks of a robot file of your own (see :mod:`sotdrake.robots.from_file`), each a
:class:`~sotdrake.exceptions.RobotDescriptionError` (or :class:`~sotdrake.exceptions.RobotFileNotFound`)
naming the file and the element, raised at load time, before the model is used:

* the path is a file, not a folder;
* the format is the one of its root element (``<robot>``: URDF, ``<sdf>``: SDF, ``<mujoco>``:
  MJCF), under a name it is read by: a URDF as ``.urdf`` or ``.xml``, an SDF as ``.sdf``, an MJCF
  as ``.xml`` (a file under another name is refused with its real format and the name to give it);
* a URDF's limits are finite, its shapes of positive size, its masses finite and ≥ 0, its
  ``<mimic>`` joints without a cycle, no joint has the link ``world`` as its child and no
  ``type="floating"`` joint joins two links (Drake would leave the child a detached free body);
* an SDF or MJCF file leaves at most one body free (the floating base): each model has one root
  link (a link no joint attaches), and a file frees at most one body (an MJCF ``<freejoint/>``, or
  the root link with ``floating_base=True``).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BodyIndex, ModelInstanceIndex

from ..exceptions import RobotDescriptionError, RobotFileNotFound
from .catalog import ROBOTS
from .mimic import leaders_first, mimic_joints
from .urdf_checks import check_masses, positive_lengths

#: Suffix → the format read under it (``.xml`` is told apart by its root element).
FORMATS = {".urdf": "urdf", ".sdf": "sdf", ".mjcf": "mjcf", ".xml": "xml"}

#: Root element → format, and the suffixes each format is read under (the first: the name to give).
_ROOTS = {"robot": "urdf", "sdf": "sdf", "mujoco": "mjcf"}
_SUFFIXES = {"urdf": (".urdf", ".xml"), "sdf": (".sdf",), "mjcf": (".xml",)}


def check_is_file(file: Path, given: object) -> None:
    """:class:`RobotFileNotFound` if ``file`` (the path ``given``) is not a file: missing, or a folder
    (the message says so, with the descriptions in it)."""
    if file.is_file():
        return
    error = RobotFileNotFound(str(given), list(ROBOTS))
    if file.is_dir():
        inside = sorted(p.name for p in file.iterdir() if p.suffix.lower() in FORMATS and p.is_file())[:5]
        hint = f" (it holds {', '.join(inside)})" if inside else ""
        error.args = (f"robot file {str(given)!r} is a folder, not a file{hint}: give the path of a URDF, SDF or MJCF file",)
    raise error


def description_format(path: Path) -> str:
    """``'urdf'``, ``'sdf'`` or ``'mjcf'``: the format of the description ``path`` by its root
    element. :class:`RobotDescriptionError`: an unknown suffix, an unknown root element, a ``.xml``
    that is not XML, or a format under a name it is not read by (the message names the real format
    and the name to give). A ``.urdf``, ``.sdf`` or ``.mjcf`` that is not XML is left to its reader."""
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise RobotDescriptionError(f"{path}: unknown description format; expected one of {sorted(FORMATS)}")
    try:
        tag = ET.parse(path).getroot().tag.rpartition("}")[2]  # (without an XML namespace)
    except (ET.ParseError, UnicodeDecodeError) as error:
        if kind != "xml":
            return kind  # (its reader says what is wrong: not UTF-8, not XML, at which line)
        raise RobotDescriptionError(f"{path}: not well-formed XML ({error})") from None
    real = _ROOTS.get(tag)
    if real is None:
        raise RobotDescriptionError(f"{path}: root element <{tag}>: expected <robot> (URDF), <sdf> or <mujoco> (MJCF)")
    suffixes = _SUFFIXES[real]
    if path.suffix.lower() not in suffixes:
        raise RobotDescriptionError(
            f"{path}: a {real.upper()} file (root element <{tag}>), which is read only under a name ending in "
            f"{' or '.join(map(repr, suffixes))}: rename it (or link it, beside its meshes) to {path.stem + suffixes[0]!r}")
    return real


def check_user_urdf(text: str, source: str) -> str:
    """``text`` with ``velocity="0"`` limits removed (no limit), after the checks of the module
    docstring: the ``lower`` and ``upper`` limits given to a revolute or prismatic joint are finite
    numbers, shapes have positive sizes, masses are finite and ≥ 0, ``<mimic>`` joints form no
    cycle, ``world`` is no joint's child and no ``floating`` joint joins two links
    (:class:`RobotDescriptionError` naming the joint or the link)."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as error:
        raise RobotDescriptionError(f"{source}: not well-formed XML ({error})") from None
    for joint in root.iter("joint"):
        _check_urdf_joint(joint, source)
    for link in root.iter("link"):
        _check_shape_sizes(link, source)
    if root.tag == "robot":
        check_masses(root, source)
        leaders_first(mimic_joints(root), source)

    def zero_velocity(match: re.Match) -> str:  # velocity="0", '0', "0e0", "-0.0": no limit
        try:
            return match.group(1) if float(match.group(3)) == 0.0 else match.group(0)
        except ValueError:
            return match.group(0)  # (the parser says what is wrong with it)

    return re.sub(r"""(<limit\b[^>]*?)\svelocity\s*=\s*(["'])(.*?)\2""", zero_velocity, text, flags=re.S)


def _check_urdf_joint(joint: ET.Element, source: str) -> None:
    """A URDF joint's finite limits; ``world`` only as a parent (it is the world frame, which a joint
    cannot move); no ``floating`` joint but from ``world`` (Drake does not model one between two
    links: it leaves the child a free body, detached from the robot)."""
    name, kind = joint.get("name", "?"), joint.get("type")
    parent, child = (None if (end := joint.find(tag)) is None else end.get("link") for tag in ("parent", "child"))
    if child == "world":
        raise RobotDescriptionError(
            f"{source}: joint {name!r} has the link 'world' as its child: 'world' is the world frame, which a joint "
            f"can only have as its parent (to weld the robot to it: parent 'world', child {parent!r})")
    if kind == "floating" and parent != "world":
        raise RobotDescriptionError(
            f"{source}: joint {name!r} is a floating joint between the links {parent!r} and {child!r}: not supported (Drake "
            f"would leave {child!r} a free body, detached from the robot); a robot has one free body, its base "
            "(floating_base=True, or a floating joint from 'world'): join the links by a fixed or a moving joint")
    if kind not in ("revolute", "prismatic"):
        return
    limit = joint.find("limit")
    for side in ("lower", "upper"):
        value = None if limit is None else limit.get(side)
        if value is None:  # URDF's default (0), as Drake reads it
            continue
        try:
            finite = bool(np.isfinite(float(value)))
        except ValueError:
            finite = False
        if not finite:
            raise RobotDescriptionError(
                f"{source}: joint {name!r} ({kind}): limit {side}={value!r} is not a finite number; give finite "
                'limits (rad or m), or make an unbounded joint type="continuous"')


#: A URDF shape's size attributes, each positive finite numbers (m).
_URDF_SIZES = {"sphere": ("radius",), "box": ("size",), "cylinder": ("radius", "length"), "capsule": ("radius", "length")}


def _check_shape_sizes(link: ET.Element, source: str) -> None:
    """:class:`RobotDescriptionError` naming the link of a shape whose size is not positive (Drake
    takes a sphere of radius 0)."""
    for geometry in link.iter("geometry"):  # (a shape elsewhere, e.g. pinocchio's <collision_checking>, names one)
        for element in geometry:
            shape = element.tag
            for field in _URDF_SIZES.get(shape, ()):
                text = element.get(field)
                if not positive_lengths(text):
                    raise RobotDescriptionError(f"{source}: link {link.get('name', '?')!r}: a {shape}'s {field} must be "
                                                f"positive finite numbers (m), got {text!r:.60}")


def attach_roots(plant: MultibodyPlant, instances: list[ModelInstanceIndex], source: object, floating_base: bool,
                 free: set[str]) -> None:
    """Weld the root link (a link no joint attaches) of each of an SDF or MJCF file's models to the
    world, or with ``floating_base`` leave it free; ``free``: the bodies the file frees itself (MJCF
    ``<freejoint/>``), never welded. :class:`RobotDescriptionError` naming the file and the links if
    a model has several root links (Drake would leave each a free body: a URDF with two root links
    is refused too), or if more than one body would be left free (the robot has one free base)."""
    children = {plant.get_joint(j).child_body().index() for j in plant.GetJointIndices()}
    roots: list[list[str]] = []
    for instance in instances:
        names = [plant.get_body(b).name() for b in plant.GetBodyIndices(instance) if b not in children and b != BodyIndex(0)]
        unattached = [name for name in names if name not in free]
        if len(unattached) > 1:
            raise RobotDescriptionError(
                f"{source}: model {plant.GetModelInstanceName(instance)!r} has {len(unattached)} links no joint attaches, "
                f"{unattached}: Drake would leave each a free body; a model has one root link: attach the others by a "
                "joint (a fixed one to carry them)")
        roots.append(unattached)
    left_free = sorted(free) + ([name for names in roots for name in names] if floating_base else [])
    if len(left_free) > 1:
        fix = "keep one <freejoint/>" if free else "weld the models' root links to the world (floating_base=False)"
        raise RobotDescriptionError(f"{source}: {len(left_free)} bodies would be free, {left_free}: a robot has at most one "
                                    f"free body, its floating base; {fix} and attach the other bodies by joints")
    for instance, names in zip(instances, roots, strict=True):
        if names and not floating_base:
            plant.WeldFrames(plant.world_frame(), plant.GetBodyByName(names[0], instance).body_frame())
