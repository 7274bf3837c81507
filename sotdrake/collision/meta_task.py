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

from ..exceptions import InvalidInput, check_name
from ..robot import Robot
from .task import DAMPER_SPEED, INFLUENCE_DISTANCE, SAFETY_DISTANCE, TaskCollision, check_margins
from .world import CollisionWorld, collision_world

if TYPE_CHECKING:
    from ..dynamics.robot_dyn import RobotDyn


class _CollisionLevel:
    """What both meta tasks hold: ``robot``, ``name``, the collision ``world`` and ``task``, built
    once the robot's type is checked. The task leaves out the pairs the solver cannot move, by the
    solver's control selection when the meta task is made (set it before)."""

    def __init__(self, robot: Robot | RobotDyn, name: str, pairs: Sequence[tuple[str, str]] | None, safety: float,
                 influence: float, xi: float, acceleration: bool):
        check_name(f"{type(self).__name__}: the name", name)
        robot.check_new_names(["task" + name])
        margins = check_margins(safety, influence, xi, robot.dt, f"{type(self).__name__}({name!r})")
        self.robot, self.name = robot, name
        self.world: CollisionWorld = collision_world(robot)
        solver = getattr(robot, "sot", None) or getattr(robot, "solver", None)
        controlled = getattr(getattr(solver, "_defaults", None), "control_selection", None)
        task = TaskCollision("task" + name, self.world, robot.dimension, robot.dt, pairs, margins, acceleration=acceleration,
                             controlled=controlled)
        robot.add_task(task)
        self.task: TaskCollision = task

    def setMargins(self, safety: float, influence: float, xi: float, context: Context | None = None) -> None:
        """See :meth:`~.task.TaskCollision.setMargins`."""
        self.task.setMargins(safety, influence, xi, context)


class MetaTaskKineCollision(_CollisionLevel):
    """Adds ``task<name>`` (a :class:`~.task.TaskCollision`) fed by the device's ``q`` and given to
    the robot's solver. ``pairs``: None for every pair, or ``(link, link)`` / ``(link, obstacle)``
    names; ``safety`` ``d_s`` (m), ``influence`` ``d_i`` (m), ``xi`` ``ξ`` (m/s). Obstacles must be
    added (:func:`~.obstacles.add_obstacle`) before the diagram's context is made; those named in
    ``pairs`` before this call."""

    def __init__(self, robot: Robot, name: str = "collision", pairs: Sequence[tuple[str, str]] | None = None,
                 safety: float = SAFETY_DISTANCE, influence: float = INFLUENCE_DISTANCE, xi: float = DAMPER_SPEED):
        if not isinstance(robot, Robot):
            raise InvalidInput(f"MetaTaskKineCollision takes the robot, got {type(robot).__name__}")
        super().__init__(robot, name, pairs, safety, influence, xi, acceleration=False)
        robot.builder.Connect(robot.device.GetOutputPort("state"), self.task.GetInputPort("position"))


class MetaTaskDynCollision(_CollisionLevel):
    """The collision level of the dynamic SoT (a :class:`~sotdrake.dynamics.robot_dyn.RobotDyn`):
    ``task<name>``, a :class:`~.task.TaskCollision` at the acceleration level, fed by the dynamic
    entity's ``position`` and ``velocity`` and given to its ``SolverDyn``; arguments as
    :class:`MetaTaskKineCollision`."""

    def __init__(self, robot: RobotDyn, name: str = "collision", pairs: Sequence[tuple[str, str]] | None = None,
                 safety: float = SAFETY_DISTANCE, influence: float = INFLUENCE_DISTANCE, xi: float = DAMPER_SPEED):
        from ..dynamics.robot_dyn import RobotDyn

        if not isinstance(robot, RobotDyn):
            raise InvalidInput(f"MetaTaskDynCollision takes the dynamic robot (RobotDyn), got {type(robot).__name__}")
        super().__init__(robot, name, pairs, safety, influence, xi, acceleration=True)
        robot.builder.Connect(robot.dynamic.GetOutputPort("position"), self.task.GetInputPort("position"))
