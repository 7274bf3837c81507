"""``MetaTaskKineCollision``: the collision task of a robot, added, named and plugged in one line.

``collision = MetaTaskKineCollision(robot); sot.push(collision)`` keeps every pair of the robot's
bodies (its SRDF and adjacency filtered, :mod:`.pairs`) and every link–obstacle pair at least
``d_s`` apart (:mod:`.task`). Place it like any task; the usual place is just under the contacts,
above the tasks it must never give way to. Only the hierarchical QP takes it (``add_sot(robot,
solver='hqp')``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from pydrake.systems.framework import Context

from ..exceptions import InvalidInput
from ..robot import Robot
from .task import DAMPER_SPEED, INFLUENCE_DISTANCE, SAFETY_DISTANCE, TaskCollision, check_margins
from .world import CollisionWorld, collision_world

if TYPE_CHECKING:
    from ..dynamics.robot_dyn import RobotDyn


class MetaTaskKineCollision:
    """Adds ``task<name>`` (a :class:`~.task.TaskCollision`) fed by the device's ``q`` and given to
    the robot's solver. ``pairs``: None for every pair, or ``(link, link)`` / ``(link, obstacle)``
    names; ``safety`` ``d_s`` (m), ``influence`` ``d_i`` (m), ``xi`` ``ξ`` (m/s). Obstacles must be
    added (:func:`~.obstacles.add_obstacle`) before the diagram's context is made; those named in
    ``pairs`` before this call."""

    def __init__(self, robot: Robot, name: str = "collision", pairs: Sequence[tuple[str, str]] | None = None,
                 safety: float = SAFETY_DISTANCE, influence: float = INFLUENCE_DISTANCE, xi: float = DAMPER_SPEED):
        if not isinstance(robot, Robot):
            raise InvalidInput(f"MetaTaskKineCollision takes the robot, got {type(robot).__name__}")
        margins = check_margins(safety, influence, xi, robot.dt, f"MetaTaskKineCollision({name!r})")
        self.robot, self.name = robot, name
        self.world: CollisionWorld = collision_world(robot)
        task = TaskCollision("task" + name, self.world, robot.dimension, robot.dt, pairs, margins)
        robot.add_task(task)
        self.task: TaskCollision = task
        robot.builder.Connect(robot.device.GetOutputPort("state"), task.GetInputPort("position"))

    def setMargins(self, safety: float, influence: float, xi: float, context: Context | None = None) -> None:
        """See :meth:`~.task.TaskCollision.setMargins`."""
        self.task.setMargins(safety, influence, xi, context)


class MetaTaskDynCollision:
    """The collision level of the dynamic SoT (a :class:`~sotdrake.dynamics.robot_dyn.RobotDyn`):
    ``task<name>``, a :class:`~.task.TaskCollision` at the acceleration level, fed by the dynamic
    entity's ``position`` and ``velocity`` and given to its ``SolverDyn``; arguments as
    :class:`MetaTaskKineCollision`."""

    def __init__(self, robot: RobotDyn, name: str = "collision", pairs: Sequence[tuple[str, str]] | None = None,
                 safety: float = SAFETY_DISTANCE, influence: float = INFLUENCE_DISTANCE, xi: float = DAMPER_SPEED):
        from ..dynamics.robot_dyn import RobotDyn

        if not isinstance(robot, RobotDyn):
            raise InvalidInput(f"MetaTaskDynCollision takes the dynamic robot (RobotDyn), got {type(robot).__name__}")
        margins = check_margins(safety, influence, xi, robot.dt, f"MetaTaskDynCollision({name!r})")
        self.robot, self.name = robot, name
        self.world: CollisionWorld = collision_world(robot)
        task = TaskCollision("task" + name, self.world, robot.dimension, robot.dt, pairs, margins, acceleration=True)
        robot.add_task(task)
        robot.builder.Connect(robot.dynamic.GetOutputPort("position"), task.GetInputPort("position"))
        self.task: TaskCollision = task

    def setMargins(self, safety: float, influence: float, xi: float, context: Context | None = None) -> None:
        """See :meth:`~.task.TaskCollision.setMargins`."""
        self.task.setMargins(safety, influence, xi, context)
