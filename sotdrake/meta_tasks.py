"""Builder helpers in the seed's vocabulary (sot-core ``meta_tasks_kine``).

A meta task adds, names and plugs the entities of one task, as sot-core does:
``feature<name>`` (the feature), ``feature<name>_ref`` (``featureDes``, the desired value),
``gain<name>`` and ``task<name>``; the task is connected to the robot's solver. Until told otherwise,
the desired value is the current one at the device's initial configuration, so a task pushed without
a target holds still.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context

from .entity import recording
from .exceptions import InvalidInput, SotError, check_finite
from .features import Feature6d, Feature6dDesired, FeatureGeneric, FeatureGenericDesired
from .features.feature6d import as_transform
from .gains import GainAdaptive, from_numbers
from .kinematics import Dynamic
from .robot import robot_of
from .selection import parse_selection
from .task import Task, TaskInequality


def _current_position(robot, context: Context | None) -> np.ndarray:
    if recording():
        raise SotError("keep() reads the current state: call it with a context, not inside attime")
    return robot.device.initial_position if context is None else robot.device.position(context)


def _task(name: str, nv: int, inequality: bool) -> Task | TaskInequality:
    return TaskInequality(name, nv) if inequality else Task(name, nv)


class MetaTaskKine6d:
    """Task on the pose of an op point: ``MetaTaskKine6d('rh', robot.dynamic, 'rh', 'right-wrist')``.

    ``opPointRef`` is an op-point name of ``robot.OperationalPointsMap``, or a joint or frame name.
    ``inequality=True`` makes ``task`` a ``TaskInequality`` (bounds on the error, ``task.setBounds``).
    """

    def __init__(self, name: str, dyn: Dynamic, opPoint: str, opPointRef: str | None = None, inequality: bool = False):
        robot = robot_of(dyn)
        self.name, self.dyn, self.opPoint, self.robot = name, dyn, opPoint, robot
        nv = robot.dimension
        position, jacobian = dyn.createOpPoint(opPoint, opPointRef or opPoint)
        self.feature = robot.add(Feature6d("feature" + name, nv))
        self.featureDes = robot.add(Feature6dDesired("feature" + name + "_ref"))
        self.gain = robot.add(GainAdaptive("gain" + name))
        self.task = robot.add_task(_task("task" + name, nv, inequality))
        connect = robot.builder.Connect
        connect(position, self.feature.GetInputPort("position"))
        connect(jacobian, self.feature.GetInputPort("Jq"))
        connect(self.featureDes.GetOutputPort("position"), self.feature.GetInputPort("reference"))
        connect(self.feature.GetOutputPort("error"), self.gain.GetInputPort("error"))
        connect(self.feature.GetOutputPort("error"), self.task.GetInputPort("error"))
        connect(self.feature.GetOutputPort("jacobian"), self.task.GetInputPort("jacobian"))
        connect(self.gain.GetOutputPort("gain"), self.task.GetInputPort("controlGain"))
        self.keep()

    @property
    def opmodif(self) -> RigidTransform | None:
        """Offset ``X_OpF`` of the controlled frame (4×4 matrix or ``RigidTransform``)."""
        return self.feature.settings().opmodif

    @opmodif.setter
    def opmodif(self, value) -> None:
        self.feature.setOpmodif(value)

    def current_pose(self, context: Context | None = None) -> RigidTransform:
        """``X_WF`` of the controlled frame (op point · opmodif) at the current configuration."""
        X = self.dyn.pose_at(self.opPoint, _current_position(self.robot, context))
        opmodif = self.feature.settings(context).opmodif
        return X if opmodif is None else X.multiply(opmodif)

    def keep(self, context: Context | None = None) -> None:
        """Desired pose ← current pose: the task holds the op point where it is."""
        self.featureDes.setPosition(self.current_pose(context), context)


class MetaTaskKineCom:
    """Task on the centre of mass (``FeatureGeneric`` over ``dynamic.com``), metres, world frame.
    ``inequality=True`` makes ``task`` a ``TaskInequality`` (e.g. a box around the desired CoM)."""

    def __init__(self, dyn: Dynamic, name: str = "com", inequality: bool = False):
        robot = robot_of(dyn)
        self.name, self.dyn, self.robot = name, dyn, robot
        nv = robot.dimension
        self.feature = robot.add(FeatureGeneric("feature" + name, 3, nv))
        self.featureDes = robot.add(FeatureGenericDesired("feature" + name + "_ref", 3))
        self.gain = robot.add(GainAdaptive("gain" + name))
        self.task = robot.add_task(_task("task" + name, nv, inequality))
        connect = robot.builder.Connect
        connect(dyn.GetOutputPort("com"), self.feature.GetInputPort("errorIN"))
        connect(dyn.GetOutputPort("Jcom"), self.feature.GetInputPort("jacobianIN"))
        connect(self.featureDes.GetOutputPort("errorIN"), self.feature.GetInputPort("reference"))
        connect(self.feature.GetOutputPort("error"), self.gain.GetInputPort("error"))
        connect(self.feature.GetOutputPort("error"), self.task.GetInputPort("error"))
        connect(self.feature.GetOutputPort("jacobian"), self.task.GetInputPort("jacobian"))
        connect(self.gain.GetOutputPort("gain"), self.task.GetInputPort("controlGain"))
        self.keep()

    def keep(self, context: Context | None = None) -> None:
        """Desired CoM ← current CoM."""
        self.featureDes.setReference(self.dyn.com_at(_current_position(self.robot, context)), context)


def gotoNd(
    task: MetaTaskKine6d | MetaTaskKineCom,
    position,
    selec: str | None = None,
    gain=None,
    context: Context | None = None,
) -> None:
    """Drive ``task`` to ``position`` (sot-core ``gotoNd``).

    ``position``: for a 6D task a 3-vector (translation, identity rotation), a 6-vector
    ``(x, y, z, roll, pitch, yaw)`` or a 4×4 matrix; for the CoM a 3-vector. ``selec``: the
    selection mask (``'111'``: X, Y, Z). ``gain``: 1 number (constant), 3 (``set(λ0, λ∞, slope)``)
    or 4 (``setByPoint(λ0, λ∞, e_ref, p)``).
    """
    # Validate everything first: a rejected gotoNd changes nothing.
    coefficients = None if gain is None else from_numbers(gain)
    if isinstance(task, MetaTaskKine6d):
        target, dimension = as_transform(position, f"gotoNd({task.name})"), 6
    elif isinstance(task, MetaTaskKineCom):
        target, dimension = check_finite(f"gotoNd({task.name})", position, (3,)), 3
    else:
        raise InvalidInput(f"gotoNd takes a MetaTaskKine6d or MetaTaskKineCom, got {type(task).__name__}")
    if selec is not None:
        parse_selection(selec, dimension)

    if isinstance(task, MetaTaskKine6d):
        task.featureDes.setPosition(target, context)
    else:
        task.featureDes.setReference(target, context)
    if selec is not None:
        task.feature.selec(selec, context)
    if coefficients is not None:
        task.gain.setCoefficients(coefficients, context)
