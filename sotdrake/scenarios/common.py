"""What several scenarios share: the gripping right hand, the support held where it stands, the
drift of held frames along a run and the fall of a floating base.

Poses are world-frame homogeneous transforms (T × 4 × 4, m), one per tick, as
``robot.dynamic.trajectory`` returns them; points are T × 3 (m).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from sotdrake import MetaTaskKine6d, MetaTaskKineCom, Robot, fall_report, tilt_of_quaternions

#: The tutorials' grip: the hand's operational point moved this far (m) along the wrist's x axis.
HAND_OFFSET = (0.1, 0.0, 0.0)


def gripping_hand(robot: Robot, op_point: str = "rh", offset: Sequence[float] = HAND_OFFSET,
                  desired_frame: bool = True) -> MetaTaskKine6d:
    """The tutorials' ``taskRH``: a 6D task named ``rh`` at the ``right-wrist`` joint whose point
    is moved by ``opmodif`` = translation ``offset`` (m, wrist frame); with ``desired_frame`` its
    error is expressed in the desired frame (``feature.frame('desired')``). Not pushed."""
    task = MetaTaskKine6d("rh", robot, op_point, robot.OperationalPointsMap["right-wrist"])
    grip = np.eye(4)
    grip[0:3, 3] = offset
    task.opmodif = grip
    if desired_frame:
        task.feature.frame("desired")
    return task


def keep_feet_and_com(robot: Robot, com_selec: str | None = None,
                      gain: float = 10.0) -> tuple[MetaTaskKine6d, MetaTaskKine6d, MetaTaskKineCom]:
    """The tutorials' support, built but not pushed: the CoM kept where it is (``keep()``, rows
    ``com_selec`` if given, e.g. ``'011'`` for x, y) and both ankles (``contactLF`` at
    ``left-ankle``, ``contactRF`` at ``right-ankle``) kept in 6D, their errors in the desired
    frame, every one with the constant ``gain`` (1/s). Returns ``(contactLF, contactRF, taskCom)``.
    (:func:`~sotdrake.hold_feet_and_com` also pushes them and keeps the build-time targets.)"""
    taskCom = MetaTaskKineCom(robot)
    taskCom.keep()
    if com_selec is not None:
        taskCom.feature.selec(com_selec)
    taskCom.gain.setConstant(gain)
    contacts = {}
    for name, joint in (("LF", "left-ankle"), ("RF", "right-ankle")):
        contact = MetaTaskKine6d("contact" + name, robot, name, robot.OperationalPointsMap[joint])
        contact.feature.frame("desired")
        contact.gain.setConstant(gain)
        contact.keep()
        contacts[name] = contact
    return contacts["LF"], contacts["RF"], taskCom


def point_on(poses: np.ndarray, offset: Sequence[float]) -> np.ndarray:
    """The point at ``offset`` (m, in the posed frame) in the world, at each tick: R·offset + p."""
    return poses[:, :3, :3] @ np.asarray(offset) + poses[:, :3, 3]


def translation_drift(poses: np.ndarray, axes: int = 3) -> np.ndarray:
    """‖p_k − p_0‖ (m) of the first ``axes`` world coordinates (3: x, y, z; 2: x, y) of the
    frame's origin, at each tick k."""
    return np.linalg.norm(poses[:, :axes, 3] - poses[0, :axes, 3], axis=1)


def rotation_drift(poses: np.ndarray) -> np.ndarray:
    """The angle (rad) of R_0ᵀ·R_k, the frame's rotation since the first tick, at each tick k:
    arccos((tr(R_0ᵀ R_k) − 1) / 2)."""
    return np.arccos(np.clip((np.einsum("kij,ij->k", poses[:, :3, :3], poses[0, :3, :3]) - 1) / 2, -1, 1))


def point_drift(points: np.ndarray, axes: int = 3) -> np.ndarray:
    """‖c_k − c_0‖ (m) of the first ``axes`` coordinates of the points (T × 3), at each tick k."""
    return np.linalg.norm(points[:, :axes] - points[0, :axes], axis=1)


def support_drift(path: Mapping[str, np.ndarray], feet: Iterable[str] = ("LF", "RF")) -> dict[str, float]:
    """How far the held support moved over the run (the largest value over the ticks and the
    ``feet``): ``max_foot_drift_m`` (translation), ``max_foot_rotation_drift_rad``,
    ``max_com_drift_m`` (x, y, z) and ``max_com_xy_drift_m``. ``path``: the feet's poses and
    ``com`` (T × 3), as ``robot.dynamic.trajectory`` returns them."""
    feet = tuple(feet)
    return {
        "max_foot_drift_m": float(max(translation_drift(path[f]).max() for f in feet)),
        "max_foot_rotation_drift_rad": float(max(rotation_drift(path[f]).max() for f in feet)),
        "max_com_drift_m": float(point_drift(path["com"]).max()),
        "max_com_xy_drift_m": float(point_drift(path["com"], 2).max()),
    }


def floating_base_fall(time: np.ndarray, state: np.ndarray, sole_slip: np.ndarray | None = None) -> dict:
    """:func:`~sotdrake.fall.fall_report` of a floating-base run: ``state`` rows start with the
    base's quaternion (w, x, y, z) and position (x, y, z, m, world); a row with a non-finite
    value is a fall. ``sole_slip``: the held soles' largest displacement (m) at each tick."""
    finite = np.all(np.isfinite(state), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return fall_report(time, np.where(finite, tilt_of_quaternions(state[:, :4]), np.nan), state[:, 6], sole_slip)
