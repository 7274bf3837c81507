"""What every meta task shares (:mod:`sotdrake.meta_tasks`): the checks made before a meta task adds
anything (the robot, the name, the entity names it would add), the value an input of a feature has in
a context, and :class:`MetaTask`, which adds and plugs a feature's gain and task as sot-core does
(``feature.error → gain.error``, ``feature.signals → task.feature``, ``gain.gain → task.controlGain``)."""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING, Any

import numpy as np
from pydrake.systems.framework import Context, InputPort

from .entity import recording
from .exceptions import InvalidInput, SotError, check_flag, check_name
from .features import Feature, FeaturePosture
from .gains import GainAdaptive
from .kinematics import Dynamic
from .ranges import MAX_TARGET_POSITION
from .robot import Robot
from .task import Task, TaskInequality, TaskPD

if TYPE_CHECKING:
    from .dynamics.robot_dyn import RobotDyn


def as_robot(robot: Robot, meta: str) -> Robot:
    """``robot`` if it is a :class:`~sotdrake.robot.Robot`, else :class:`InvalidInput` naming the meta
    task ``meta`` (and saying so when ``robot.dynamic`` was passed, as sot-core's scripts do)."""
    if not isinstance(robot, Robot):
        raise InvalidInput(f"{meta} takes the robot (e.g. {meta}('rh', robot, ...)), got {type(robot).__name__}"
                           + (": pass the robot, not robot.dynamic" if isinstance(robot, Dynamic) else ""))
    return robot


def new_task(robot: Robot, meta: str, name: str, feature: bool = True, reference: bool = False,
             inequality: bool = False, pd: bool = False) -> Robot:
    """``robot``, after the checks that must pass before a meta task adds anything: the robot, the
    name, ``inequality`` and ``pd`` not both, and no entity yet of the names it adds (``feature<name>``
    with ``feature``, ``feature<name>_ref`` with ``reference``, ``gain<name>``, ``task<name>``)."""
    robot = as_robot(robot, meta)
    check_name(f"{meta}: the name", name)
    inequality, pd = check_flag(f"{meta}: inequality", inequality), check_flag(f"{meta}: pd", pd)
    if inequality and pd:
        raise InvalidInput(f"{meta}({name!r}): a task is an inequality or a PD task, not both")
    names = ["gain" + name, "task" + name] + ["feature" + name] * feature + ["feature" + name + "_ref"] * reference
    robot.check_new_names(names)
    return robot


def check_start(meta: str, name: str, what: str, position: np.ndarray) -> None:
    """:class:`InvalidInput` if ``position`` (m, world), where the task's reference starts (``what``:
    the op point or the CoM), is beyond the ±:data:`~sotdrake.ranges.MAX_TARGET_POSITION` a reference
    may be: checked before the meta task adds anything."""
    if not np.all(np.abs(position) <= MAX_TARGET_POSITION):
        raise InvalidInput(f"{meta}({name!r}): {what} starts at {np.round(position, 3).tolist()} m, beyond the "
                           f"±{MAX_TARGET_POSITION:g} m a reference may be (a robot in mm rather than m?)")


def posture_feature(meta: str, name: str, robot: Robot | RobotDyn, posture: np.ndarray) -> FeaturePosture:
    """``feature<name>``, a :class:`FeaturePosture` of ``robot``'s joints towards ``posture`` (not
    added yet); :class:`InvalidInput` if the robot has no joint besides its floating base (the
    feature would select nothing)."""
    feature = FeaturePosture("feature" + name, robot.model.plant, posture)
    if not len(feature.layout.joints_v):
        raise InvalidInput(f"{meta}({name!r}): the robot {robot.model.name!r} has no joint besides its floating base: "
                           "a posture task has nothing to hold")
    return feature


def check_not_recording(what: str) -> None:
    """:class:`SotError` if called inside ``attime`` (``what`` reads a context's current state, which a
    recorded command cannot know)."""
    if recording():
        raise SotError(f"{what} reads the current state: call it with a context, not inside attime")


def input_value(port: InputPort, context: Context) -> Any:
    """The value ``port`` (an input of a feature) has in the root diagram ``context``, as a copy: the
    value read refers into the context's cache, which the next evaluation overwrites, and keeps that
    context alive (settings holding it would keep their own context alive)."""
    system = port.get_system()
    try:
        own = system.GetMyContextFromRoot(context)
    except (RuntimeError, TypeError) as error:
        raise InvalidInput(f"context: expected the root diagram context (from which {system.get_name()}'s "
                           f"input {port.get_name()!r} is evaluated), got another context") from error
    return copy.copy(port.Eval(own))


class MetaTask:
    """The gain and the task of a feature, plugged as sot-core does, and the task given to the solver."""

    def _finish(self, robot: Robot, name: str, feature: Feature, inequality: bool = False, pd: bool = False) -> None:
        """The gain and the task of ``feature`` (after :func:`new_task`'s checks), connected and added."""
        self.robot, self.name = robot, name
        self.feature = feature
        self.gain = robot.add(GainAdaptive("gain" + name, robot.dt))
        nv = robot.dimension
        if inequality:
            task: Task = TaskInequality("task" + name, nv)
        else:
            task = TaskPD("task" + name, nv, robot.dt, max(nv, feature.dimension)) if pd else Task("task" + name, nv)
        self.task = robot.add_task(task)
        connect = robot.builder.Connect
        connect(feature.GetOutputPort("error"), self.gain.GetInputPort("error"))
        connect(feature.GetOutputPort("signals"), self.task.GetInputPort("feature"))
        connect(self.gain.GetOutputPort("gain"), self.task.GetInputPort("controlGain"))
