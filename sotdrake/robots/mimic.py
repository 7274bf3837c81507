"""A URDF's ``<mimic>`` joints, which Drake's parser couples (``q_f = multiplier q_l + offset``):
read from the text, and applied to a posture so that it is one the physics holds."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
from pydrake.multibody.plant import MultibodyPlant


def mimic_table(urdf_text: str) -> dict[str, tuple[str, float, float]]:
    """The URDF's moving ``<mimic>`` joints: follower → (leader, multiplier, offset), as Drake's
    parser couples them (``q_f = multiplier q_l + offset``; by default 1 and 0)."""
    return mimic_joints(ET.fromstring(urdf_text))


def mimic_joints(root: ET.Element) -> dict[str, tuple[str, float, float]]:
    """:func:`mimic_table` of a URDF already parsed (its root element)."""
    table = {}
    for joint in root.iter("joint"):
        mimic = joint.find("mimic")
        if mimic is not None and joint.get("type") != "fixed":
            table[joint.get("name", "")] = (mimic.get("joint", ""), float(mimic.get("multiplier") or 1.0),
                                            float(mimic.get("offset") or 0.0))
    return table


def follow_mimics(plant: MultibodyPlant, mimic: dict[str, tuple[str, float, float]], q: np.ndarray) -> np.ndarray:
    """``q`` with each mimic follower of ``mimic`` (:func:`mimic_table`) set from its leader, as the
    physics holds them, then clipped into the follower's limits."""
    q = q.copy()
    for follower, (leader, multiplier, offset) in mimic.items():
        if plant.HasJointNamed(follower) and plant.HasJointNamed(leader):
            joint, lead = plant.GetJointByName(follower), plant.GetJointByName(leader)
            if joint.num_positions() == lead.num_positions() == 1:
                value = multiplier * q[lead.position_start()] + offset
                q[joint.position_start()] = np.clip(value, joint.position_lower_limits()[0], joint.position_upper_limits()[0])
    return q
