"""A task's target and controlled point drawn in Meshcat, read from the Context at every publish.

The target is the task's desired value (``featureDes``), so it follows ``gotoNd`` whenever it is
called: at build time, inside ``attime`` or from a live shell. It is drawn as a bright sphere with a
crosshair through it whose arms reach out of the robot's meshes; the point the task controls (the op
point moved by ``opmodif``) is a smaller sphere, so the two meet when the task converges. When
Meshcat records (``MeshcatVisualizer.StartRecording``), every pose is recorded too.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat, Rgba, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from .entity import own_context
from .exceptions import InvalidInput, check_finite, check_name, check_number, check_type

if TYPE_CHECKING:
    from .meta_tasks import MetaTaskKine6d

TARGET_COLOR = Rgba(1.0, 0.1, 0.05, 1.0)
POINT_COLOR = Rgba(1.0, 0.85, 0.0, 1.0)
#: The radii (m) and publish periods (s) a :class:`TargetMarker` takes.
RADIUS_RANGE = (1e-6, 100.0)
PUBLISH_PERIOD_RANGE = (1e-4, 10.0)
#: The methods of ``Meshcat`` a marker draws with.
_DRAWING = ("SetObject", "SetLineSegments", "SetTransform", "SetProperty")


def _crosshair(half_length: float) -> tuple[np.ndarray, np.ndarray]:
    """Three segments through the origin along x, y and z, as Meshcat's line segments (3×3 each)."""
    axes = half_length * np.eye(3)
    return -axes, axes


class TargetMarker(LeafSystem):
    """Draws a task's target (``<path>/target``) and its controlled point (``<path>/point``).

    Inputs: ``desired_pose`` (``X_WF*``, the task's desired pose, a ``RigidTransform``) and, optional,
    ``op_point_pose`` (``X_WOp``, the op point's pose). Outputs: ``target_position`` (``p_WF*``, m)
    and ``point_position`` (``p_WF``, m: the op point moved by ``opmodif``; NaN without
    ``op_point_pose``). Publishes at initialization, every ``publish_period`` (s) and when forced.

    Checked before anything is declared or drawn (:class:`InvalidInput` naming the argument):
    ``meshcat`` a ``Meshcat`` (or an object with its drawing methods), ``path`` a non-empty string,
    ``opmodif`` None or a finite ``RigidTransform``, ``radius`` in :data:`RADIUS_RANGE` (m), ``rgba``
    None or an ``Rgba``, ``publish_period`` in :data:`PUBLISH_PERIOD_RANGE` (s).
    """

    def __init__(self, meshcat: Meshcat, path: str = "/target", opmodif: RigidTransform | None = None,
                 radius: float = 0.02, rgba: Rgba | None = None, publish_period: float = 1 / 60):
        if not all(callable(getattr(meshcat, method, None)) for method in _DRAWING):
            raise InvalidInput(f"TargetMarker: meshcat: expected a Meshcat (start_meshcat()), got {type(meshcat).__name__}")
        check_name("TargetMarker: path (a Meshcat path such as '/target')", path)
        if opmodif is not None:
            check_type("TargetMarker: opmodif", opmodif, RigidTransform, "None or a RigidTransform")
            check_finite("TargetMarker: opmodif", opmodif.GetAsMatrix4())
        radius = check_number("TargetMarker: radius", radius, *RADIUS_RANGE, " m")
        if rgba is not None:
            check_type("TargetMarker: rgba", rgba, Rgba, "None or a pydrake.geometry.Rgba")
        publish_period = check_number("TargetMarker: publish_period", publish_period, *PUBLISH_PERIOD_RANGE, " s")
        LeafSystem.__init__(self)
        self._meshcat, self._path = meshcat, path.rstrip("/") or "/target"
        self._opmodif = RigidTransform() if opmodif is None else RigidTransform(opmodif)
        self._rgba = TARGET_COLOR if rgba is None else rgba
        self._radius = radius
        self.desired_pose = self.DeclareAbstractInputPort("desired_pose", AbstractValue.Make(RigidTransform()))
        self.op_point_pose = self.DeclareAbstractInputPort("op_point_pose", AbstractValue.Make(RigidTransform()))
        self.DeclareVectorOutputPort("target_position", 3, self._target_position)
        self.DeclareVectorOutputPort("point_position", 3, self._point_position)
        self.DeclareInitializationPublishEvent(self._publish)
        self.DeclarePeriodicPublishEvent(publish_period, 0.0, self._publish)
        self.DeclareForcedPublishEvent(self._publish)
        self._draw()

    def _draw(self) -> None:
        meshcat, path = self._meshcat, self._path
        meshcat.SetObject(f"{path}/target/sphere", Sphere(self._radius), self._rgba)
        start, end = _crosshair(5 * self._radius)
        meshcat.SetLineSegments(f"{path}/target/crosshair", start, end, 3.0, self._rgba)
        meshcat.SetObject(f"{path}/point", Sphere(0.5 * self._radius), POINT_COLOR)
        meshcat.SetProperty(f"{path}/point", "visible", False)

    def _target_position(self, context: Context, output) -> None:
        output.SetFromVector(self.desired_pose.Eval(context).translation())

    def _point_position(self, context: Context, output) -> None:
        if not self.op_point_pose.HasValue(context):
            output.SetFromVector(np.full(3, np.nan))
            return
        output.SetFromVector(self.op_point_pose.Eval(context).multiply(self._opmodif).translation())

    def _publish(self, context: Context) -> EventStatus:
        t = context.get_time()
        self._meshcat.SetTransform(f"{self._path}/target", RigidTransform(self.get_output_port(0).Eval(context)), t)
        if self.op_point_pose.HasValue(context):
            self._meshcat.SetProperty(f"{self._path}/point", "visible", True, t)
            self._meshcat.SetTransform(f"{self._path}/point", RigidTransform(self.get_output_port(1).Eval(context)), t)
        return EventStatus.Succeeded()


def desired_position(task: MetaTaskKine6d, context: Context) -> np.ndarray:
    """The desired position (m) of a ``MetaTaskKine6d`` in the root diagram ``context``: the last
    ``gotoNd``'s (at build time, in ``attime`` or live), or its moving target's, as the task sees it.
    A ``task`` without ``featureDes`` or a ``context`` of another diagram (or a leaf context, or
    None): :class:`InvalidInput`."""
    desired = getattr(task, "featureDes", None)
    if not isinstance(desired, LeafSystem):
        raise InvalidInput(f"desired_position: task must be a MetaTaskKine6d (with a featureDes), got {task!r:.60}")
    return np.array(desired.GetOutputPort("position").Eval(own_context(desired, context)).translation())
