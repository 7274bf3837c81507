"""A URDF's ``<mimic>`` joints, which Drake's parser couples (``q_f = multiplier q_l + offset``):
read from the text, and applied to a posture so that it is one the physics holds (leaders first: a
follower may lead another; a cycle of followers is refused)."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
from pydrake.multibody.plant import MultibodyPlant

from ..exceptions import RobotDescriptionError


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


def leaders_first(mimic: dict[str, tuple[str, float, float]], source: object = "URDF") -> list[str]:
    """The followers of ``mimic`` (:func:`mimic_table`), each after its leader when the leader follows
    a joint too (a chain ``j2 → j1 → j0`` in any order of the file gives ``j1, j2``).
    :class:`RobotDescriptionError` naming the joints of a cycle (``j0`` mimics ``j1`` which mimics
    ``j0``: no joint leads them; ``source`` names the file)."""
    order: list[str] = []
    done: set[str] = set()
    for start in mimic:
        chain: list[str] = []
        joint = start
        while joint in mimic and joint not in done:
            if joint in chain:
                cycle = [*chain[chain.index(joint):], joint]
                raise RobotDescriptionError(f"{source}: the <mimic> joints {' → '.join(map(repr, cycle))} follow each other in a "
                                            "cycle: no joint leads them; one of them must be the leader (no <mimic>)")
            chain.append(joint)
            joint = mimic[joint][0]
        order.extend(reversed(chain))
        done.update(chain)
    return order


def follow_mimics(plant: MultibodyPlant, mimic: dict[str, tuple[str, float, float]], q: np.ndarray) -> np.ndarray:
    """``q`` with each mimic follower of ``mimic`` (:func:`mimic_table`) set from its leader, as the
    physics holds them, then clipped into the follower's limits; leaders first (:func:`leaders_first`):
    in a chain, a follower is set from its leader's new value."""
    q = q.copy()
    for follower in leaders_first(mimic):
        leader, multiplier, offset = mimic[follower]
        if plant.HasJointNamed(follower) and plant.HasJointNamed(leader):
            joint, lead = plant.GetJointByName(follower), plant.GetJointByName(leader)
            if joint.num_positions() == lead.num_positions() == 1:
                value = multiplier * q[lead.position_start()] + offset
                q[joint.position_start()] = np.clip(value, joint.position_lower_limits()[0], joint.position_upper_limits()[0])
    return q
