"""``RobotModel``: a finalized plant of a robot with what the SoT needs to know about it, and the
reference posture read from an SRDF."""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, FrameIndex, JointActuatorIndex

from ..exceptions import FrameNotFound, OperationalPointNotFound
from .srdf import read_group_state

log = logging.getLogger(__name__)

#: The robot loader (:func:`.loader.load_robot`), registered by :mod:`.loader` at its import, so that
#: :meth:`RobotModel.with_meshes` can load a robot again without this module importing the loader.
_loader: list[Callable[..., RobotModel]] = []


def register_loader(load: Callable[..., RobotModel]) -> None:
    """Make ``load`` (:func:`.loader.load_robot`) the loader :meth:`RobotModel.with_meshes` uses."""
    _loader[:] = [load]


class OperationalPoints(dict[str, str]):
    """``robot.OperationalPointsMap``: op-point name → joint, link or frame name. An unknown name
    raises :class:`~sotdrake.exceptions.OperationalPointNotFound` (a ``KeyError``) listing the op
    points and the close matches (``'right_hand'`` → ``'right-wrist'``)."""

    def __missing__(self, key: str) -> str:
        raise OperationalPointNotFound(str(key), list(self))


@dataclass
class RobotModel:
    """A finalized plant of the robot with what the SoT needs to know about it.

    ``half_sitting`` is the reference posture ``q0`` (Drake's ``q``): the SRDF's (``half_sitting``
    for the humanoids, e.g. ``standing`` for quadrupeds, the tucked arms for PR2), else every joint
    at 0 clipped into its limits; see :attr:`reference_posture`.
    """

    plant: MultibodyPlant
    variant: str
    OperationalPointsMap: dict[str, str]
    half_sitting: np.ndarray
    fixed_base: bool = False
    scene_graph: SceneGraph | None = None
    srdf_path: Path | None = None
    name: str = "talos"
    base: str = "free"  #: ``free``, ``planar`` or ``fixed`` (see :data:`sotdrake.robots.catalog.BASES`)
    #: sole op point → contact rectangle ``(x_min, x_max, y_min, y_max)`` (m, sole frame), where known
    sole_rectangles: dict[str, tuple[float, float, float, float]] = field(default_factory=dict)
    #: the description file of a robot loaded by path (None for the catalog's robots)
    source_path: Path | None = None
    #: the keyword arguments it was loaded with (to load it again, e.g. with meshes)
    load_options: dict[str, Any] = field(default_factory=dict, repr=False)
    #: the URDF's ``<mimic>`` joints: follower → (leader, multiplier, offset), ``q_f = m q_l + offset``
    mimic: dict[str, tuple[str, float, float]] = field(default_factory=dict)
    _frames: dict[str, Frame] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.OperationalPointsMap, OperationalPoints):
            self.OperationalPointsMap = OperationalPoints(self.OperationalPointsMap)

    @property
    def nq(self) -> int:
        return self.plant.num_positions()

    @property
    def nv(self) -> int:
        return self.plant.num_velocities()

    @property
    def reference_posture(self) -> np.ndarray:
        """The reference posture ``q0`` (the same array as ``half_sitting``)."""
        return self.half_sitting

    def frame(self, name: str) -> Frame:
        """Frame of an operational point (``'right-wrist'``), a frame (a link's) or a joint (its child
        frame); a name that is both a frame's and a joint's is the frame's.

        Raises :class:`FrameNotFound` listing operational points and frame names.
        """
        if not isinstance(name, str):
            raise FrameNotFound(repr(name), list(self.OperationalPointsMap))
        frame = self.find_frame(name)
        if frame is None:
            plant = self.plant
            frames = {plant.get_frame(FrameIndex(i)).name() for i in range(plant.num_frames())}
            raise FrameNotFound(name, [*self.OperationalPointsMap, *sorted(frames)])
        return frame

    def find_frame(self, name: str) -> Frame | None:
        """:meth:`frame`, or None for a name that is none of those."""
        if name in self._frames:
            return self._frames[name]
        plant, target = self.plant, self.OperationalPointsMap.get(name, name)
        bases = list(plant.GetFloatingBaseBodies())
        if target == "root_joint" and not plant.HasJointNamed(target) and bases:
            frame = plant.get_body(bases[0]).body_frame()  # sot-talos' name of the free flyer
        elif plant.HasFrameNamed(target):  # (a link's name before a joint's: a joint named after a link is common)
            frame = plant.GetFrameByName(target)
        elif plant.HasJointNamed(target):
            frame = plant.GetJointByName(target).frame_on_child()
        else:
            return None
        self._frames[name] = frame
        return frame

    def with_meshes(self) -> RobotModel:
        """The same robot with visual and collision meshes, on its own plant and SceneGraph."""
        load_robot = _loader[0] if _loader else None
        if load_robot is None:  # the loader registers itself when sotdrake.robots is imported
            raise RuntimeError("with_meshes: import sotdrake.robots first (it registers the robot loader)")
        if self.source_path is not None:
            return load_robot(self.source_path, meshes=True, **self.load_options)
        return load_robot(self.name, self.variant, meshes=True, base=self.base, **self.load_options)

    def joint_limits(self) -> dict[str, np.ndarray]:
        """``position_lower/upper`` (nq, ±inf on the floating base), ``velocity_lower/upper`` (nv),
        ``effort`` (one per actuator, in actuator order)."""
        plant = self.plant
        return {
            "position_lower": plant.GetPositionLowerLimits(),
            "position_upper": plant.GetPositionUpperLimits(),
            "velocity_lower": plant.GetVelocityLowerLimits(),
            "velocity_upper": plant.GetVelocityUpperLimits(),
            "effort": np.array(
                [plant.get_joint_actuator(JointActuatorIndex(i)).effort_limit()
                 for i in range(plant.num_actuators())]
            ),
        }


def posture_from_srdf(plant: MultibodyPlant, srdf_path: Path, name: str | tuple[str, ...], q: np.ndarray | None = None) -> np.ndarray:
    """Drake ``q`` of SRDF reference postures (``name``: one ``group_state`` or several applied in
    order), starting from ``q`` (default: the plant's default positions; joints not listed keep
    their value). A ``root_joint`` entry ``(x, y, z, qx, qy, qz, qw)`` sets the floating base pose;
    it is ignored when the base is not floating."""
    context = plant.CreateDefaultContext()
    if q is not None:
        plant.SetPositions(context, q)
    for group in (name,) if isinstance(name, str) else name:
        skipped, state = [], read_group_state(srdf_path, group)  # (a reduced model leaves some joints out)
        body = next(iter(plant.GetFloatingBaseBodies()), None)
        if body is None:  # welded or planar base: the SRDF base pose does not apply (nor counts)
            state.pop("root_joint", None)
        for joint_name, value in state.items():
            if joint_name == "root_joint":
                x, y, z, qx, qy, qz, qw = value
                pose = RigidTransform(Quaternion(np.array([qw, qx, qy, qz]) / np.linalg.norm([qw, qx, qy, qz])), [x, y, z])
                plant.SetFreeBodyPose(context, plant.get_body(body), pose)
            elif plant.HasJointNamed(joint_name) and plant.GetJointByName(joint_name).num_positions() == value.size:
                joint = plant.GetJointByName(joint_name)
                q_all = plant.GetPositions(context)
                q_all[joint.position_start() : joint.position_start() + joint.num_positions()] = value
                plant.SetPositions(context, q_all)
            else:
                if plant.HasJointNamed(joint_name):
                    log.warning("%s: group state %r: joint %r has %d positions, the SRDF gives %d values: left out", srdf_path,
                                group, joint_name, plant.GetJointByName(joint_name).num_positions(), value.size)
                skipped.append(joint_name)
        if skipped and len(skipped) == len(state):
            log.warning("%s: group state %r: none of its %d joints is one of the model's (with as many positions): "
                        "an SRDF of another robot? (%s)", srdf_path, group, len(skipped), ", ".join(skipped[:8]))
    return plant.GetPositions(context)
