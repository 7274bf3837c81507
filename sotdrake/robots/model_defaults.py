"""What a model loaded from a file gets when the call does not say: its operational points and its
reference posture ``q0`` (see :mod:`sotdrake.robots.from_file` for the rules), and the checks of
those given."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BodyIndex, Frame

from ..exceptions import InvalidInput, NotFound, check_finite
from .mimic import follow_mimics
from .model import OperationalPoints, RobotModel, posture_from_srdf
from .srdf import PostureNotFound, group_state_names, read_end_effectors

log = logging.getLogger(__name__)

#: SRDF group states tried, in order, when no reference posture is named.
PREFERRED_POSTURES = ("half_sitting", "standing", "default", "home", "ready")


def default_operational_points(model: RobotModel) -> dict[str, str]:
    """The SRDF's end effectors, the leaf links and, for a floating base, ``waist`` (see
    :mod:`sotdrake.robots.from_file`): the floating base, or the model's own link (or joint) named
    ``waist`` when it has one. A default op point never hides a frame: an end effector named like
    another frame of the model (iCub's ``r_foot`` on ``r_sole``) is left out with a log warning,
    the name staying that frame's."""
    plant = model.plant
    points: dict[str, str] = {}
    if model.srdf_path is not None:
        effectors = read_end_effectors(model.srdf_path)
        points.update({n: link for n, link in effectors.items() if plant.HasFrameNamed(link)})
        unknown = sorted(f"{n} ({link})" for n, link in effectors.items() if n not in points)
        if unknown:
            log.warning("%s: the end effectors %s are on links the model does not have: not op points", model.srdf_path, unknown)
        hiding = {n: named.name() for n, link in points.items()
                  if (named := _frame_named(plant, n)) is not None and named.index() != plant.GetFrameByName(link).index()}
        if hiding:
            log.warning("%s: the end effectors %s are named like other frames of the model, which they would hide: not op "
                        "points (each name is its own frame)", model.srdf_path,
                        sorted(f"{n} ({points.pop(n)}, hiding {frame})" for n, frame in hiding.items()))
    parents = {plant.get_joint(j).parent_body().index() for j in plant.GetJointIndices()}
    for index in range(1, plant.num_bodies()):
        body = plant.get_body(BodyIndex(index))
        if body.index() not in parents:
            points.setdefault(body.name(), body.name())
    if plant.GetFloatingBaseBodies():
        points["waist"] = "waist" if _frame_named(plant, "waist") is not None else "root_joint"
    return points


def _frame_named(plant: MultibodyPlant, name: str) -> Frame | None:
    """The frame ``name`` names in ``plant`` without op points: a frame's (a link's) or, else, a
    joint's child frame (as :meth:`RobotModel.frame` reads a name); None if neither."""
    if plant.HasFrameNamed(name):
        return plant.GetFrameByName(name)
    return plant.GetJointByName(name).frame_on_child() if plant.HasJointNamed(name) else None


def check_op_point_names(model: RobotModel, points: Mapping[str, str], where: str) -> None:
    """:class:`InvalidInput` if an op point of ``points`` (name → target) is named like a frame or
    joint of the model that is not its own target's frame: the op point would hide that frame (a
    task on the link would control another body), as a meta task's op point may not (``where``
    names the source in the message). An op point named like its own target (``tool`` → ``tool``)
    is fine."""
    for name, target in points.items():
        named = _frame_named(model.plant, name)
        if named is not None and named.index() != model.frame(target).index():
            raise InvalidInput(f"{where} {name!r} on {target!r}: {name!r} already names another frame of {model.name} "
                               f"({named.name()!r}); give the op point another name")


def operational_points_of(model: RobotModel, given: Mapping[str, str] | Sequence[str] | None) -> OperationalPoints:
    """The op-point map of ``model``: ``given`` (checked: each target must be a joint, link or frame
    of the model, else :class:`~sotdrake.exceptions.FrameNotFound` listing them, and no name may
    hide another frame, :func:`check_op_point_names`) or the defaults."""
    if given is None:
        return OperationalPoints(default_operational_points(model))
    if isinstance(given, str) or not isinstance(given, (Mapping, Sequence)):
        raise InvalidInput(
            f"operational_points: expected a dict of op-point name → frame name, or a list of frame names, got {given!r:.100}"
        )
    points = dict(given) if isinstance(given, Mapping) else {name: name for name in given}
    for name, target in points.items():
        if not isinstance(name, str) or not isinstance(target, str):
            raise InvalidInput(f"operational_points: names and frames are strings, got {name!r}: {target!r}")
        model.frame(target)  # raises FrameNotFound naming the model's frames
    check_op_point_names(model, points, "operational_points: op point")
    return OperationalPoints(points)


def posture_of(model: RobotModel, given: Any, start: np.ndarray | None = None) -> np.ndarray:
    """The reference posture (see :mod:`sotdrake.robots.from_file`), clipped into the joint limits; a group
    state or a ``{joint: value}`` changes ``start`` (default: the default positions)."""
    plant = model.plant
    lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    q = np.clip(plant.GetDefaultPositions() if start is None else np.array(start, dtype=float), lower, upper)
    srdf = model.srdf_path
    if isinstance(given, str):
        if srdf is None:
            raise InvalidInput(
                f"reference_posture={given!r} names an SRDF group state, but the robot has no SRDF: "
                "give srdf='path/to/robot.srdf', or the posture as an array or {joint: value}"
            )
        names = group_state_names(srdf)
        if given not in names:
            raise PostureNotFound(given, names)
        q = posture_from_srdf(plant, srdf, given, q)
    elif isinstance(given, Mapping):
        context = plant.CreateDefaultContext()
        plant.SetPositions(context, q)
        for joint_name, value in given.items():
            if not isinstance(joint_name, str) or not plant.HasJointNamed(joint_name):
                raise NotFound(str(joint_name), [plant.get_joint(j).name() for j in plant.GetJointIndices()]).but(
                    "reference_posture: a joint's name")
            joint = plant.GetJointByName(joint_name)
            values = check_finite(f"reference_posture[{joint_name!r}]", np.atleast_1d(value), (joint.num_positions(),))
            q[joint.position_start() : joint.position_start() + joint.num_positions()] = values
        _normalize_base_quaternions(plant, q)
    elif given is not None:
        q = check_finite("reference_posture (q0, Drake's order)", given, (plant.num_positions(),)).copy()
        _normalize_base_quaternions(plant, q)
    elif srdf is not None:
        names = group_state_names(srdf)
        preferred = [n for n in PREFERRED_POSTURES if n in names] or names[:1]
        if preferred:
            q = posture_from_srdf(plant, srdf, preferred[0], q)
    return follow_mimics(plant, model.mimic, np.clip(q, lower, upper))


def _normalize_base_quaternions(plant: MultibodyPlant, q: np.ndarray) -> None:
    """Each floating base's quaternion in ``q`` made unit (the given one, normalized); a zero one is
    refused (:class:`InvalidInput`)."""
    for body in plant.GetFloatingBaseBodies():
        start = plant.get_body(body).floating_positions_start()
        norm = float(np.linalg.norm(q[start:start + 4]))
        if norm == 0.0:
            raise InvalidInput(f"reference_posture: the floating base's quaternion q[{start}:{start + 4}] (w, x, y, z) "
                               "is zero; e.g. (1, 0, 0, 0) for no rotation")
        q[start:start + 4] /= norm
