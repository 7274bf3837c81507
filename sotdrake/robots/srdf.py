"""Reference postures (``<group_state>``) read from an SRDF file."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..exceptions import NotFound, RobotDescriptionError


class PostureNotFound(NotFound):
    kind = "reference posture"


def read_group_state(srdf_path: Path, name: str) -> dict[str, np.ndarray]:
    """Joint values of the SRDF ``<group_state name=...>``, keyed by joint name.

    A floating ``root_joint`` is given as in the SRDF: ``(x, y, z, qx, qy, qz, qw)``. A value
    that is not finite numbers, a ``root_joint`` that is not seven of them with a non-zero
    quaternion: :class:`RobotDescriptionError` naming the file, the group state and the joint.
    """
    states = {s.get("name", ""): s for s in srdf_root(srdf_path).iter("group_state")}
    if name not in states:
        raise PostureNotFound(name, states)
    return {j.get("name", ""): _joint_value(srdf_path, name, j) for j in states[name].iter("joint")}


def _joint_value(srdf_path: Path, group: str, joint: ET.Element) -> np.ndarray:
    joint_name, text = joint.get("name", ""), joint.get("value", "")
    where = f"{srdf_path}: group_state {group!r}, joint {joint_name!r}"
    try:
        value = np.array([float(x) for x in text.split()])
    except ValueError:
        raise RobotDescriptionError(f"{where}: value={text!r} is not a list of numbers") from None
    if not np.isfinite(value).all():
        raise RobotDescriptionError(f"{where}: value={text!r} is not finite")
    if joint_name == "root_joint" and (value.size != 7 or not np.any(value[3:])):
        raise RobotDescriptionError(f"{where}: expected the base pose as seven numbers x y z qx qy qz qw with a "
                                    f"non-zero quaternion, got {text!r}")
    return value


def srdf_root(srdf_path: Path) -> ET.Element:
    """The SRDF's root element; :class:`RobotDescriptionError` if it is not well-formed XML text, or
    if it describes links (a URDF given as the SRDF)."""
    try:
        root = ET.parse(srdf_path).getroot()
    except (ET.ParseError, UnicodeDecodeError) as error:
        raise RobotDescriptionError(f"{srdf_path}: the SRDF is not well-formed XML ({error})") from None
    if root.find("link") is not None:
        raise RobotDescriptionError(f"{srdf_path}: given as the SRDF, but it describes links (<link>): a URDF, not an SRDF")
    return root


def group_state_names(srdf_path: Path) -> list[str]:
    """The names of the SRDF's ``<group_state>`` elements, in file order."""
    return [s.get("name", "") for s in srdf_root(srdf_path).iter("group_state")]


def read_end_effectors(srdf_path: Path) -> dict[str, str]:
    """The SRDF's ``<end_effector name=... parent_link=...>``: end-effector name → the link it is
    attached to (the op point is that link's frame)."""
    root = srdf_root(srdf_path)
    return {e.get("name", ""): e.get("parent_link", "") for e in root.iter("end_effector") if e.get("parent_link")}
