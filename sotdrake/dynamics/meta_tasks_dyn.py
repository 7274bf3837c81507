"""Dynamic meta tasks (sot-dyninv ``MetaTaskDyn6d``, ``MetaTaskDynCom``, ``MetaTaskDynPosture``),
and ``MetaTaskDynMomentum``, which damps the centroidal momentum (``FeatureMomentum``).

Each adds ``feature<name>`` (an existing feature, unchanged), ``feature<name>_ref`` (its desired
value) and ``task<name>`` (:class:`.task_dyn_pd.TaskDynPD`), plugged as in the kinematic meta tasks,
and connects the task to the robot's ``SolverDyn``. Desired values start as the current ones at the
robot's initial configuration (the task holds still until told otherwise).
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context

from ..centroidal import base_rows
from ..exceptions import InvalidInput, check_name, check_type
from ..features import Feature6d, Feature6dDesired, FeatureGeneric, FeatureGenericDesired, FeatureMomentum
from ..features.base import check_mask
from ..meta_task_base import check_start, posture_feature
from .robot_dyn import RobotDyn
from .task_dyn_pd import TaskDynPD
from .terms import base_translation_rows


def _new_names(robot: RobotDyn, name: str, *suffixes: str) -> None:
    """Refuse, before anything is added, a name that is not a non-empty string or whose entities
    (``task<name>``, ``feature<name>`` and ``feature<name><suffix>``) exist already."""
    check_type("a dynamic meta task's robot", robot, RobotDyn, "the RobotDyn (e.g. MetaTaskDyn6d('rh', robot, 'rh', 'right-wrist'))")
    check_name("a dynamic meta task's name", name)
    robot.check_new_names(["task" + name, "feature" + name, *("feature" + name + suffix for suffix in suffixes)])


class _MetaTaskDyn:
    def _finish(self, robot: RobotDyn, name: str, feature, kp: float, kv: float | None, dimension: int | None = None,
                exact_drift: bool = False) -> None:
        self.robot, self.name, self.feature = robot, name, feature
        self.task = robot.add_task(TaskDynPD("task" + name, robot.dimension, robot.dt, kp, kv, dimension, exact_drift))
        robot.builder.Connect(feature.GetOutputPort("signals"), self.task.GetInputPort("feature"))
        if dimension is not None:  # (its drift and reference acceleration have all the feature's components)
            robot.builder.Connect(feature.GetOutputPort("selected_rows"), self.task.GetInputPort("rows"))


class MetaTaskDyn6d(_MetaTaskDyn):
    """Pose of an op point (``Feature6d``, frame ``'desired'``), e.g. a foot to lift."""

    def __init__(self, name: str, robot: RobotDyn, opPoint: str, opPointRef: str | None = None,
                 kp: float = 100.0, kv: float | None = None):
        """The task's ``reference_acceleration`` input takes the 6 error rows' ``s̈*`` (with the
        default frame ``'desired'`` and a fixed desired rotation: ``(p̈*, 0)``)."""
        _new_names(robot, name, "_ref")
        TaskDynPD.check_gains("task" + name, kp, kv, robot.dt)  # before anything is added
        self.opPoint = opPoint
        robot.dynamic.check_op_point(opPoint, opPointRef or opPoint)
        start = robot.dynamic.pose_at(opPointRef or opPoint, robot.q0).translation()
        check_start("MetaTaskDyn6d", name, f"the op point {opPoint!r}", start)
        position, jacobian = robot.dynamic.createOpPoint(opPoint, opPointRef or opPoint)
        feature = robot.add(Feature6d("feature" + name, robot.dimension))
        self.featureDes = robot.add(Feature6dDesired("feature" + name + "_ref"))
        connect = robot.builder.Connect
        connect(position, feature.GetInputPort("position"))
        connect(jacobian, feature.GetInputPort("Jq"))
        connect(self.featureDes.GetOutputPort("position"), feature.GetInputPort("reference"))
        connect(self.featureDes.GetOutputPort("velocity"), feature.GetInputPort("reference_velocity"))
        self._finish(robot, name, feature, kp, kv, dimension=6)
        self.keep()

    def initial_pose(self) -> RigidTransform:
        return self.robot.dynamic.pose_at(self.opPoint, self.robot.q0)

    def keep(self, context: Context | None = None) -> None:
        """Desired pose ← the op point's pose at the initial configuration."""
        self.featureDes.setPosition(self.initial_pose(), context)


class MetaTaskDynCom(_MetaTaskDyn):
    """The centre of mass (``FeatureGeneric`` over ``dynamic.com``) with the exact CoM drift."""

    def __init__(self, robot: RobotDyn, name: str = "com", kp: float = 100.0, kv: float | None = None):
        _new_names(robot, name, "_ref")
        TaskDynPD.check_gains("task" + name, kp, kv, robot.dt)  # before anything is added
        if base_translation_rows(robot.dynamic.layout) is None:
            raise InvalidInput(f"MetaTaskDynCom({name!r}): {robot.model.name} has no floating base: the dynamic CoM task's "
                               "Jacobian and drift are those of the base's translation (a fixed base holds the CoM)")
        check_start("MetaTaskDynCom", name, "the centre of mass", robot.dynamic.com_at(robot.q0))
        feature = robot.add(FeatureGeneric("feature" + name, 3, robot.dimension))
        self.featureDes = robot.add(FeatureGenericDesired("feature" + name + "_ref", 3))
        connect = robot.builder.Connect
        connect(robot.dynamic.GetOutputPort("com"), feature.GetInputPort("errorIN"))
        connect(robot.dynamic.GetOutputPort("Jcom"), feature.GetInputPort("jacobianIN"))
        connect(self.featureDes.GetOutputPort("errorIN"), feature.GetInputPort("reference"))
        connect(self.featureDes.GetOutputPort("velocity"), feature.GetInputPort("reference_velocity"))
        self._finish(robot, name, feature, kp, kv, dimension=3, exact_drift=True)
        connect(robot.dynamic.GetOutputPort("com_drift"), self.task.GetInputPort("drift"))
        self.keep()

    def initial_com(self) -> np.ndarray:
        return self.robot.dynamic.com_at(self.robot.q0)

    def keep(self, context: Context | None = None) -> None:
        self.featureDes.setReference(self.initial_com(), context)


class MetaTaskDynPosture(_MetaTaskDyn):
    """Every joint towards the initial posture (``FeaturePosture``; the free flyer left free)."""

    def __init__(self, robot: RobotDyn, name: str = "posture", kp: float = 25.0, kv: float | None = None):
        _new_names(robot, name)
        TaskDynPD.check_gains("task" + name, kp, kv, robot.dt)  # before anything is added
        feature = robot.add(posture_feature("MetaTaskDynPosture", name, robot, robot.q0))
        robot.builder.Connect(robot.dynamic.GetOutputPort("position"), feature.GetInputPort("state"))
        self._finish(robot, name, feature, kp, kv)


class MetaTaskDynMomentum(_MetaTaskDyn):
    """The centroidal momentum (``FeatureMomentum``) as an acceleration task,
    ``A_G q̈ = −K_v (h_G − h*) − Ȧ_G v`` on the rows of ``mask`` (default ``'111'``: the angular
    momentum about the CoM; ``h* = 0`` until ``feature.setReference``): the momentum error decays
    at the rate ``K_v`` (1/s). The exact ``Ȧ_G v`` (the dynamic entity's ``momentum_drift``, its
    selected rows) is the task's ``drift``; ``feature.selec`` changes the mask later, at build or
    run time. A floating base only."""

    def __init__(self, robot: RobotDyn, name: str = "momentum", kv: float = 10.0, mask: str = "111"):
        _new_names(robot, name)
        TaskDynPD.check_gains("task" + name, 0.0, kv, robot.dt)  # before anything is added
        base_rows(robot.dynamic.layout)
        check_mask(mask, 6, f"MetaTaskDynMomentum({name!r})")
        feature = robot.add(FeatureMomentum("feature" + name, robot.dimension))
        feature.selec(mask)
        connect = robot.builder.Connect
        connect(robot.dynamic.GetOutputPort("momentum_matrix"), feature.GetInputPort("momentum_matrix"))
        self._finish(robot, name, feature, 0.0, kv, dimension=6, exact_drift=True)
        connect(robot.dynamic.GetOutputPort("momentum_drift"), self.task.GetInputPort("drift"))
