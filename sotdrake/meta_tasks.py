"""Builder helpers in the seed's vocabulary (sot-core ``meta_tasks_kine``).

A meta task adds, names and plugs the entities of one task, as sot-core does:
``feature<name>`` (the feature), ``feature<name>_ref`` (``featureDes``, the desired value, where
the feature has one), ``gain<name>`` and ``task<name>``; the task is connected to the robot's
solver. A meta task takes the :class:`~sotdrake.robot.Robot` (sot-core passes ``robot.dynamic``; here
the robot carries its dynamic entity, its device and its solver): ``MetaTaskKine6d('rh', robot, 'rh',
'right-wrist')``. Until told otherwise, a desired value is the current one at the device's initial
configuration, so a task pushed without a target holds still.

``keep(context)`` and ``current_pose(context)`` read the value the *feature itself sees* in that
context: its input, computed by the diagram's own ``dynamic`` entity from whatever ``q`` the diagram
feeds it (the device's ``q`` in open loop, the measured one in closed loop), as pink's
``set_target_from_configuration`` does. Without a context (at build time, before any context exists)
they use the device's initial configuration. ``inequality=True`` makes the task a
``TaskInequality`` (bounds on its error); ``pd=True`` a ``TaskPD``.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context, OutputPort

from .atomic import in_builder
from .centroidal import base_rows
from .configuration import Layout
from .entity import command_group
from .exceptions import InvalidInput, check_finite, check_number
from .features import (
    Feature,
    Feature6d,
    Feature6dDesired,
    FeatureGeneric,
    FeatureGenericDesired,
    FeatureJointLimits,
    FeatureRelative6d,
    FeatureVisualPoint,
)
from .features.base import check_mask
from .features.feature6d import as_transform
from .features.manipulability import FeatureManipulability
from .features.momentum import FeatureMomentum
from .gain_checks import check_gain
from .gains import constant, from_numbers
from .manipulability import upstream_coordinates
from .meta_task_base import MetaTask, as_robot, check_not_recording, check_start, input_value, new_task, posture_feature
from .ranges import MAX_TARGET_POSITION
from .robot import Robot, check_not_elsewhere
from .robots import TALOS_GRIPPERS
from .task import TaskInequality


class MetaTaskKine6d(MetaTask):
    """Task on the pose of an op point: ``MetaTaskKine6d('rh', robot, 'rh', 'right-wrist')``.

    ``opPointRef`` is an op-point name of ``robot.OperationalPointsMap``, or a joint or frame name.
    """

    def __init__(self, name: str, robot: Robot, opPoint: str, opPointRef: str | None = None,
                 inequality: bool = False, pd: bool = False):
        robot = new_task(robot, "MetaTaskKine6d", name, reference=True, inequality=inequality, pd=pd)
        dyn = robot.dynamic
        self.dyn, self.opPoint = dyn, opPoint
        dyn.check_op_point(opPoint, opPointRef or opPoint)
        check_start("MetaTaskKine6d", name, f"the op point {opPoint!r}",
                    dyn.pose_at(opPointRef or opPoint, robot.device.initial_position).translation())
        position, jacobian = dyn.createOpPoint(opPoint, opPointRef or opPoint)
        feature = robot.add(Feature6d("feature" + name, robot.dimension))
        self.featureDes = robot.add(Feature6dDesired("feature" + name + "_ref"))
        connect = robot.builder.Connect
        connect(position, feature.GetInputPort("position"))
        connect(jacobian, feature.GetInputPort("Jq"))
        connect(self.featureDes.GetOutputPort("position"), feature.GetInputPort("reference"))
        connect(self.featureDes.GetOutputPort("velocity"), feature.GetInputPort("reference_velocity"))
        self._finish(robot, name, feature, inequality, pd)
        self.keep()

    @property
    def opmodif(self) -> RigidTransform | None:
        """Offset ``X_OpF`` of the controlled frame (4×4 matrix or ``RigidTransform``)."""
        return self.feature.settings().opmodif

    @opmodif.setter
    def opmodif(self, value) -> None:
        self.feature.setOpmodif(value)

    def current_pose(self, context: Context | None = None) -> RigidTransform:
        """``X_WF`` of the controlled frame (op point · opmodif) as the feature sees it in the root
        diagram ``context``; without one, at the device's initial configuration."""
        check_not_recording("current_pose()")
        if context is None:
            X = self.dyn.pose_at(self.opPoint, self.robot.device.initial_position)
        else:
            X = input_value(self.feature.GetInputPort("position"), context)
        opmodif = self.feature.settings(context).opmodif
        return X if opmodif is None else X.multiply(opmodif)

    def keep(self, context: Context | None = None) -> None:
        """Desired pose ← current pose: the task holds the op point where it is."""
        self.featureDes.setPosition(self.current_pose(context), context)


class MetaTaskKineCom(MetaTask):
    """Task on the centre of mass (``FeatureGeneric`` over ``dynamic.com``), metres, world frame."""

    def __init__(self, robot: Robot, name: str = "com", inequality: bool = False, pd: bool = False):
        robot = new_task(robot, "MetaTaskKineCom", name, reference=True, inequality=inequality, pd=pd)
        self.dyn = dyn = robot.dynamic
        check_start("MetaTaskKineCom", name, "the centre of mass", dyn.com_at(robot.device.initial_position))
        feature = robot.add(FeatureGeneric("feature" + name, 3, robot.dimension))
        self.featureDes = robot.add(FeatureGenericDesired("feature" + name + "_ref", 3))
        connect = robot.builder.Connect
        connect(dyn.GetOutputPort("com"), feature.GetInputPort("errorIN"))
        connect(dyn.GetOutputPort("Jcom"), feature.GetInputPort("jacobianIN"))
        connect(self.featureDes.GetOutputPort("errorIN"), feature.GetInputPort("reference"))
        connect(self.featureDes.GetOutputPort("velocity"), feature.GetInputPort("reference_velocity"))
        self._finish(robot, name, feature, inequality, pd)
        self.keep()

    def keep(self, context: Context | None = None) -> None:
        """Desired CoM ← current CoM, as the feature sees it in ``context`` (see the module docstring)."""
        check_not_recording("keep()")
        if context is None:
            com = self.dyn.com_at(self.robot.device.initial_position)
        else:
            com = input_value(self.feature.GetInputPort("errorIN"), context)
        self.featureDes.setReference(com, context)


class MetaTaskKinePosture(MetaTask):
    """Task on the posture (``FeaturePosture``): by default every joint towards the device's
    initial configuration (half-sitting for TALOS), the floating base left free."""

    def __init__(self, robot: Robot, name: str = "posture", pd: bool = False):
        robot = new_task(robot, "MetaTaskKinePosture", name, pd=pd)
        feature = robot.add(posture_feature("MetaTaskKinePosture", name, robot, robot.device.initial_position))
        robot.builder.Connect(robot.device.GetOutputPort("state"), feature.GetInputPort("state"))
        self._finish(robot, name, feature, pd=pd)


class MetaTaskKine6dRel(MetaTask):
    """Task on the pose of op point A with respect to op point B (``FeatureRelative6d``), e.g. one
    hand with respect to the other. The desired relative pose starts as the current one;
    ``featureDes`` holds it (``X_BA*``) and, for a moving one, its velocity in B's axes
    (``featureDes.setVelocity((ω*, ṗ*))``), the feed-forward of ``errordot``.
    ``inequality=True``: a ``TaskInequality`` on the relative error (e.g. a hand kept in front of
    the waist)."""

    def __init__(self, name: str, robot: Robot, opPoint: str, opPointBase: str,
                 opPointRef: str | None = None, opPointBaseRef: str | None = None, inequality: bool = False):
        robot = new_task(robot, "MetaTaskKine6dRel", name, reference=True, inequality=inequality)
        dyn = robot.dynamic
        self.dyn, self.opPoint, self.opPointBase = dyn, opPoint, opPointBase
        if opPoint == opPointBase:
            raise InvalidInput(f"MetaTaskKine6dRel({name!r}): op point {opPoint!r} relative to itself")
        dyn.check_op_point(opPointBase, opPointBaseRef or opPointBase)  # (both checked before either is declared)
        a, Ja = dyn.createOpPoint(opPoint, opPointRef or opPoint)
        b, Jb = dyn.createOpPoint(opPointBase, opPointBaseRef or opPointBase)
        feature = robot.add(FeatureRelative6d("feature" + name, robot.dimension))
        self.featureDes = robot.add(Feature6dDesired("feature" + name + "_ref"))
        connect = robot.builder.Connect
        for port, source in (("position", a), ("Jq", Ja), ("positionRef", b), ("JqRef", Jb)):
            connect(source, feature.GetInputPort(port))
        connect(self.featureDes.GetOutputPort("position"), feature.GetInputPort("reference"))
        connect(self.featureDes.GetOutputPort("velocity"), feature.GetInputPort("reference_velocity"))
        self._finish(robot, name, feature, inequality)
        self.keep()

    def keep(self, context: Context | None = None) -> None:
        """Desired relative pose ← current relative pose, as the feature sees it in ``context``."""
        check_not_recording("keep()")
        if context is None:
            q = self.robot.device.initial_position
            X_WA, X_WB = self.dyn.pose_at(self.opPoint, q), self.dyn.pose_at(self.opPointBase, q)
        else:
            X_WA = input_value(self.feature.GetInputPort("position"), context)
            X_WB = input_value(self.feature.GetInputPort("positionRef"), context)
        X_BA = X_WB.inverse().multiply(X_WA)
        self.featureDes.setPosition(X_BA, context)


class MetaTaskVisualPoint(MetaTask):
    """Look at a point: the point's image in the camera ``opPointRef`` (an optical frame: z forward)
    is driven to ``s*`` (default the image centre). Connect ``point`` (and, for a moving point,
    ``point_velocity``) with :meth:`plugPoint`, or set a fixed point with :meth:`setPoint`."""

    def __init__(self, name: str, robot: Robot, opPoint: str = "camera", opPointRef: str = "rgbd_rgb_optical_frame"):
        robot = new_task(robot, "MetaTaskVisualPoint", name)
        position, jacobian = robot.dynamic.createOpPoint(opPoint, opPointRef)
        feature = robot.add(FeatureVisualPoint("feature" + name, robot.dimension))
        robot.builder.Connect(position, feature.GetInputPort("position"))
        robot.builder.Connect(jacobian, feature.GetInputPort("Jq"))
        self._finish(robot, name, feature)

    def plugPoint(self, point: OutputPort, velocity: OutputPort | None = None) -> None:
        for what, port in (("point", point), ("velocity", velocity)):
            if port is not None and not isinstance(port, OutputPort):
                raise InvalidInput(f"{self.name}.plugPoint: {what} must be an output port (3 numbers, world frame), "
                                   f"got {type(port).__name__}")
        self.robot.builder.Connect(point, self.feature.GetInputPort("point"))
        if velocity is not None:
            self.robot.builder.Connect(velocity, self.feature.GetInputPort("point_velocity"))

    def setPoint(self, point) -> None:
        """A fixed point (world frame, m), for the diagram's lifetime."""
        from pydrake.systems.primitives import ConstantVectorSource

        source = self.robot.add(ConstantVectorSource(check_finite("point", point, (3,))), f"point_{self.name}")
        self.plugPoint(source.get_output_port())


class MetaTaskKineMomentum(MetaTask):
    """Task on the centroidal momentum (``FeatureMomentum`` over ``dynamic.momentum_matrix``):
    ``A_G v = h*`` on the selected rows, by default ``mask='111'``, the angular momentum about the
    CoM, with ``h* = 0`` (``feature.setReference``): the whole body turns as little as it can about
    its CoM. A floating base only (a fixed base carries the momentum: :class:`InvalidInput`)."""

    def __init__(self, robot: Robot, name: str = "momentum", mask: str = "111"):
        robot = new_task(robot, "MetaTaskKineMomentum", name)
        base_rows(Layout.of(robot.model.plant))  # a fixed base is refused before anything is added
        check_mask(mask, 6, f"MetaTaskKineMomentum({name!r})")
        feature = robot.add(FeatureMomentum("feature" + name, robot.dimension))
        feature.selec(mask)
        robot.builder.Connect(robot.dynamic.GetOutputPort("momentum_matrix"), feature.GetInputPort("momentum_matrix"))
        self._finish(robot, name, feature)


class MetaTaskKineManipulability(MetaTask):
    """Keep an op point's manipulability above a floor: ``μ ≥ floor`` (``FeatureManipulability``
    under a ``TaskInequality``, gain ``gain`` 1/s: μ may approach the floor at most exponentially).
    ``opPoint``: an op point (``'right-wrist'``) or a frame; ``rows``: a mask over ``J_WF``'s rows
    (``'111000'``: the translation); ``joints``: the joints whose columns count (e.g. one arm's;
    None: every velocity). Push it above the task it protects. :class:`FrameNotFound` for an
    unknown frame, :class:`NotFound` for an unknown joint, before anything is added."""

    def __init__(self, name: str, robot: Robot, opPoint: str, floor: float, rows: str = "111000",
                 joints: list[str] | None = None, gain: float = 10.0):
        robot = new_task(robot, "MetaTaskKineManipulability", name)
        floor = check_number(f"MetaTaskKineManipulability({name!r}): floor", floor, 0.0, 1e6)
        gain = check_number(f"MetaTaskKineManipulability({name!r}): gain", gain, 1e-6, 1e4, " 1/s")
        check_gain(constant(gain), robot.dt, f"MetaTaskKineManipulability({name!r}) gain")
        robot.model.frame(opPoint)  # an unknown frame is refused before anything is added
        if isinstance(joints, str):
            raise InvalidInput(f"MetaTaskKineManipulability({name!r}): joints is a list of joint names, got the string {joints!r:.60}")
        columns = None if joints is None else ~robot.velocity_selection(excluding=joints)
        feature = FeatureManipulability("feature" + name, robot.dimension, upstream_coordinates(robot.model.plant), rows, columns)
        robot.add(feature)
        position, jacobian = robot.dynamic.createOpPoint(opPoint, opPoint)
        robot.builder.Connect(position, feature.GetInputPort("position"))
        robot.builder.Connect(jacobian, feature.GetInputPort("Jq"))
        self._finish(robot, name, feature, inequality=True)
        self.gain.setConstant(gain)
        self.task.setBounds([floor], [np.inf])


class MetaTaskKineFeature(MetaTask):
    """The gain and the task of a feature of your own: ``MetaTaskKineFeature('knee', robot, feature)``
    adds ``feature`` to the builder (if it is not added yet), then ``gain<name>`` (a
    ``GainAdaptive``, λ = 1/s until set) and ``task<name>`` (a ``Task``; ``inequality=True``: a
    ``TaskInequality``, then ``task.setBounds``; ``pd=True``: a ``TaskPD``), plugged as the other
    meta tasks are: ``feature.error → gain.error``, ``feature.signals → task.feature``,
    ``gain.gain → task.controlGain``, the task connected to the robot's solver. Connect the
    feature's own inputs (e.g. ``robot.device``'s ``state``, an op point of ``robot.dynamic``)."""

    def __init__(self, name: str, robot: Robot, feature: Feature, inequality: bool = False, pd: bool = False):
        robot = as_robot(robot, "MetaTaskKineFeature")
        if not isinstance(feature, Feature):
            raise InvalidInput(f"MetaTaskKineFeature({name!r}): expected a feature (Feature6d, FeatureGeneric …), "
                               f"got {type(feature).__name__}")
        if feature.nv != robot.dimension:
            raise InvalidInput(f"MetaTaskKineFeature({name!r}): the feature has nv = {feature.nv}, the robot {robot.dimension}")
        new_task(robot, "MetaTaskKineFeature", name, feature=False, inequality=inequality, pd=pd)
        check_not_elsewhere(robot.builder, feature, f"MetaTaskKineFeature({name!r}): feature")
        if not in_builder(robot.builder, feature):  # (a feature of that name already there is another system)
            robot.check_new_names([feature.get_name()])
            robot.add(feature)
        self._finish(robot, name, feature, inequality, pd)


class MetaTaskKineJointLimits(MetaTask):
    """Keep every joint with finite limits ``[l, u]`` inside them, a ``margin`` (a fraction of its
    range, dimensionless) away: :class:`~sotdrake.features.FeatureJointLimits`
    (``e = 2(q - l)/(u - l) - 1``, ±1 on the limits) as a ``TaskInequality`` with bounds
    ``-(1 - 2·margin) ≤ e ≤ 1 - 2·margin`` and a constant ``gain`` (1/s: a joint approaches its
    bound at most exponentially at that rate). One line: ``limits = MetaTaskKineJointLimits(robot);
    sot.push(limits)``; only the hierarchical QP takes inequalities (``add_sot(robot,
    solver='hqp')``). ``inequality=False``: an equality task that centres the joints (``e → 0``),
    for the basic ``SOT``, usually at the lowest priority. ``joint_names``: the joints it covers."""

    def __init__(self, robot: Robot, name: str = "jointLimits", margin: float = 0.05, gain: float = 10.0,
                 inequality: bool = True):
        robot = new_task(robot, "MetaTaskKineJointLimits", name, inequality=inequality)
        margin = check_number(f"MetaTaskKineJointLimits({name!r}) margin (fraction of each joint's range)", margin, 0.0, 0.45)
        gain = check_number(f"MetaTaskKineJointLimits({name!r}) gain (one number)", gain, 1e-6, 1e4, " 1/s")
        check_gain(constant(gain), robot.dt, f"MetaTaskKineJointLimits({name!r}) gain")
        plant = robot.model.plant
        feature = FeatureJointLimits("feature" + name, plant)
        if feature.dimension == 0:
            raise InvalidInput(f"MetaTaskKineJointLimits({name!r}): {robot.model.name} has no joint with finite limits")
        robot.add(feature)
        self._joint_names = list(feature.joint_names)
        robot.builder.Connect(robot.device.GetOutputPort("state"), feature.GetInputPort("state"))
        self._finish(robot, name, feature, inequality)
        self.gain.setConstant(gain)
        if inequality:
            bound = np.full(feature.dimension, 1.0 - 2.0 * margin)
            assert isinstance(self.task, TaskInequality)
            self.task.setBounds(-bound, bound)

    @property
    def joint_names(self) -> list[str]:
        """The joints the task covers (those with finite limits), in the order of its rows."""
        return list(self._joint_names)


def hold_feet_and_com(robot: Robot, sot, gain: float = 10.0, com: bool = True):
    """The tutorial's support: ``contactRF``, ``contactLF`` (both ankles kept where they are) and,
    with ``com``, the CoM held, each with a constant ``gain``, pushed in that order. Returns the
    meta tasks (``contactRF``, ``contactLF``, ``taskCom`` or None).

    With the basic ``SOT`` (which has no joint limits) and no control selection set yet, the
    robot's gripper joints (:data:`~sotdrake.robots.TALOS_GRIPPERS`, which start on their limit)
    are left out of the control, as the tutorial does:
    ``sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))``."""
    robot = as_robot(robot, "hold_feet_and_com")
    gain = check_number("hold_feet_and_com: gain", gain, 0.0, 1e4, " 1/s")
    check_gain(constant(gain), robot.dt, "hold_feet_and_com gain")
    feet = [(name, robot.OperationalPointsMap[op]) for name, op in (("contactRF", "right-ankle"), ("contactLF", "left-ankle"))]
    q0 = robot.device.initial_position
    for name, frame in feet:  # (everything checked before anything is added)
        new_task(robot, "hold_feet_and_com", name, reference=True)
        robot.dynamic.check_op_point(name[-2:], frame)
        check_start("hold_feet_and_com", name, f"the op point {frame!r}", robot.dynamic.pose_at(frame, q0).translation())
    if com:
        new_task(robot, "hold_feet_and_com", "com", reference=True)
        check_start("hold_feet_and_com", "com", "the centre of mass", robot.dynamic.com_at(q0))
    plant = robot.model.plant
    grippers = [joint for joint in TALOS_GRIPPERS if plant.HasJointNamed(joint)]
    if grippers and not getattr(sot, "accepts_inequalities", True) and sot.settings().control_selection is None:
        sot.setControlSelection(robot.velocity_selection(excluding=grippers))
    contacts = []
    for name, frame in feet:
        contact = MetaTaskKine6d(name, robot, name[-2:], frame)
        contact.gain.setConstant(gain)
        sot.push(contact.task.name)
        contacts.append(contact)
    taskCom = None
    if com:
        taskCom = MetaTaskKineCom(robot)
        taskCom.gain.setConstant(gain)
        sot.push(taskCom.task.name)
    return contacts[0], contacts[1], taskCom


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
    if coefficients is not None:
        check_gain(coefficients, getattr(getattr(task, "gain", None), "dt", None), f"gotoNd({getattr(task, 'name', task)!r}) gain")
    if isinstance(task, MetaTaskKine6d):
        target, dimension = as_transform(position, f"gotoNd({task.name})"), 6
    elif isinstance(task, MetaTaskKineCom):
        target, dimension = check_finite(f"gotoNd({task.name}) position (m)", position, (3,), MAX_TARGET_POSITION), 3
    else:
        raise InvalidInput(f"gotoNd takes a MetaTaskKine6d or MetaTaskKineCom, got {type(task).__name__}"
                           + (": pass the meta task itself" if isinstance(task, str) else ""))
    if selec is not None:
        check_mask(selec, dimension, f"gotoNd({task.name}) selec")
    if context is not None:  # each entity changed must find its context in it: the root's (not one entity's own)
        changed = [task.featureDes] + ([task.feature] if selec is not None else []) + ([task.gain] if coefficients is not None else [])
        for entity in changed:
            entity.own_context(context)

    with command_group(f"gotoNd({task.name!r})"):
        if isinstance(task, MetaTaskKine6d):
            task.featureDes.setPosition(target, context)
        else:
            task.featureDes.setReference(target, context)
        if selec is not None:
            task.feature.selec(selec, context)
        if coefficients is not None:
            task.gain.setCoefficients(coefficients, context)
