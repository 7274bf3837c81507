"""Reference postures (``<group_state>``) read from an SRDF file."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..exceptions import NotFound


class PostureNotFound(NotFound):
    kind = "reference posture"


def read_group_state(srdf_path: Path, name: str) -> dict[str, np.ndarray]:
    """Joint values of the SRDF ``<group_state name=...>``, keyed by joint name.

    A floating ``root_joint`` is given as in the SRDF: ``(x, y, z, qx, qy, qz, qw)``.
    """
    root = ET.parse(srdf_path).getroot()
    states = {s.get("name", ""): s for s in root.iter("group_state")}
    if name not in states:
        raise PostureNotFound(name, states)
    return {j.get("name", ""): np.array([float(x) for x in j.get("value", "").split()]) for j in states[name].iter("joint")}


def group_state_names(srdf_path: Path) -> list[str]:
    """The names of the SRDF's ``<group_state>`` elements, in file order."""
    return [s.get("name", "") for s in ET.parse(srdf_path).getroot().iter("group_state")]


def read_end_effectors(srdf_path: Path) -> dict[str, str]:
    """The SRDF's ``<end_effector name=... parent_link=...>``: end-effector name → the link it is
    attached to (the op point is that link's frame)."""
    root = ET.parse(srdf_path).getroot()
    return {e.get("name", ""): e.get("parent_link", "") for e in root.iter("end_effector") if e.get("parent_link")}
