"""The toolbox's features against finite differences: Jacobians (stepping q on the manifold) and
``errordot`` (moving the reference), at random TALOS configurations, through their systems."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from sotdrake.configuration import Layout
from sotdrake.exceptions import InvalidInput
from sotdrake.features import Feature1D, FeatureJointLimits
from sotdrake.lie import exp_so3
from sotdrake.meta_tasks import (
    MetaTaskKine6d,
    MetaTaskKine6dRel,
    MetaTaskKineCom,
    MetaTaskKinePosture,
    MetaTaskVisualPoint,
)
from sotdrake.robot import Robot
from sotdrake.selection import parse_selection
from tests.conftest import random_configuration
from tests.finite_differences import manifold_jacobian
from tests.test_features import feature_at


@pytest.fixture(scope="module")
def rig(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    posture = MetaTaskKinePosture(robot)
    for i in range(6):
        posture.feature.selectDof(i, True)  # the floating base too
    relative = MetaTaskKine6dRel("hands", robot, "rh", "lh", "right-wrist", "left-wrist")
    gaze = MetaTaskVisualPoint("gaze", robot)
    point = robot.add(ConstantVectorSource(np.array([1.5, 0.2, 1.3])), "point")
    point_velocity = robot.add(ConstantVectorSource(np.array([0.1, -0.3, 0.2])), "point_velocity")
    gaze.plugPoint(point.get_output_port(), point_velocity.get_output_port())
    limits = robot.add(FeatureJointLimits("featurejl", talos_model.plant))
    builder.Connect(robot.device.GetOutputPort("state"), limits.GetInputPort("state"))
    hand = MetaTaskKine6d("rh6", robot, "rh6", "right-wrist")
    one = robot.add(Feature1D("feature1d", talos_model.nv))
    for a, b in (("error", "errorIN"), ("jacobian", "jacobianIN"), ("errordot", "errordotIN")):
        builder.Connect(hand.feature.GetOutputPort(a), one.GetInputPort(b))
    features = {"posture": posture.feature, "relative": relative.feature, "gaze": gaze.feature,
                "joint_limits": limits, "feature1d": one}
    return robot, features, dict(posture=posture, relative=relative, hand=hand, point=point), builder.Build()


@pytest.mark.parametrize("name", ["posture", "relative", "gaze", "joint_limits", "feature1d"])
@pytest.mark.parametrize("seed", range(3))
def test_jacobian_by_finite_differences(rig, name, seed):
    robot, features, metas, diagram = rig
    rng = np.random.default_rng(seed)
    layout = Layout.of(robot.model.plant)
    context = diagram.CreateDefaultContext()
    q = random_configuration(robot.model, rng, spread=0.3)
    q[4:7] = robot.model.half_sitting[4:7]  # keep the point in front of the camera
    robot.device.set_position(context, q)
    if name == "posture":
        metas["posture"].feature.setPosture(random_configuration(robot.model, rng, spread=0.3), context)
    if name == "relative":
        X = metas["relative"].featureDes.settings(context).position
        rotation = X.rotation().multiply(RotationMatrix(exp_so3(rng.uniform(-1, 1, 3))))
        metas["relative"].featureDes.setPosition(RigidTransform(rotation, X.translation() + 0.1), context)
    if name == "feature1d":
        metas["hand"].featureDes.setPosition(metas["hand"].current_pose(context).translation() + 0.2, context)
    feature = features[name]
    e, J = feature_at(robot, feature, context, q)
    assert np.linalg.norm(e) > 1e-3
    numeric = manifold_jacobian(lambda q: feature_at(robot, feature, context, q)[0], q, layout, robot.model.nv)
    np.testing.assert_allclose(J, numeric, atol=2e-6 * max(1.0, np.abs(J).max()))


def errordot_at(feature, context):
    return feature.GetOutputPort("errordot").Eval(feature.GetMyContextFromRoot(context)).copy()


@pytest.mark.parametrize("frame", ["desired", "current"])
def test_feature6d_errordot_by_moving_the_target(talos_model, frame):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    task = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    task.feature.frame(frame)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    rng = np.random.default_rng(7)
    X0 = task.current_pose(context)
    Xd = RigidTransform(X0.rotation().multiply(RotationMatrix(exp_so3(rng.uniform(-1, 1, 3)))), X0.translation() + [0.2, -0.1, 0.1])
    V = rng.normal(size=6)  # (ω*, ṗ*), world
    h = 1e-6

    def error_with_target(s):
        moved = RigidTransform(RotationMatrix(exp_so3(V[:3] * s) @ Xd.rotation().matrix()), Xd.translation() + V[3:] * s)
        task.featureDes.setPosition(moved, context)
        return task.feature.GetOutputPort("error").Eval(task.feature.GetMyContextFromRoot(context)).copy()

    numeric = (error_with_target(h) - error_with_target(-h)) / (2 * h)
    task.featureDes.setPosition(Xd, context)
    task.featureDes.setVelocity(V, context)
    np.testing.assert_allclose(errordot_at(task.feature, context), numeric, atol=1e-6)


def test_moving_targets_feed_forward_reaches_the_task(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    com = MetaTaskKineCom(robot)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    com.featureDes.setVelocity([0.01, -0.02, 0.0], context)
    com.gain.setConstant(3.0, context)
    np.testing.assert_allclose(errordot_at(com.feature, context), [-0.01, 0.02, 0.0])
    level = com.task.GetOutputPort("task").Eval(com.task.GetMyContextFromRoot(context))
    np.testing.assert_allclose(level.reference, [0.01, -0.02, 0.0], atol=1e-12)  # -λ·0 - ė_ref
    assert level.is_equality


def test_the_relative_task_takes_its_references_velocity(rig):
    """``MetaTaskKine6dRel.featureDes.setVelocity`` reaches the feature's ``errordot`` (it was 0)."""
    robot, features, metas, diagram = rig
    context = diagram.CreateDefaultContext()
    relative = metas["relative"]
    relative.featureDes.setVelocity([0.0, 0.0, 0.5, 0.2, 0.0, 0.0], context)
    own = relative.feature.GetMyContextFromRoot(context)
    e_dot = relative.feature.GetOutputPort("errordot").Eval(own)
    R = relative.featureDes.settings(context).position.rotation().matrix()  # at X_BA* (e = 0): −R*ᵀ ṗ*, −R*ᵀ ω*
    np.testing.assert_allclose(e_dot, np.concatenate([-R.T @ [0.2, 0.0, 0.0], -R.T @ [0.0, 0.0, 0.5]]), atol=1e-9)
    relative.featureDes.setVelocity(np.zeros(6), context)
    assert not relative.feature.GetOutputPort("errordot").Eval(own).any()


def test_visual_point_errordot_by_moving_the_point(rig):
    robot, features, metas, diagram = rig
    context = diagram.CreateDefaultContext()
    gaze = features["gaze"]
    point_port = gaze.GetInputPort("point")
    velocity = np.array([0.1, -0.3, 0.2])
    own = gaze.GetMyContextFromRoot(context)
    h = 1e-6
    values = []
    for s in (h, -h):
        point_port.FixValue(own, np.array([1.5, 0.2, 1.3]) + s * velocity)
        values.append(gaze.GetOutputPort("error").Eval(own).copy())
    point_port.FixValue(own, np.array([1.5, 0.2, 1.3]))
    np.testing.assert_allclose(gaze.GetOutputPort("errordot").Eval(own), (values[0] - values[1]) / (2 * h), atol=1e-7)


def test_joint_limits_feature_is_sot_core_centring(talos_model):
    feature = FeatureJointLimits("jl", talos_model.plant)
    context = feature.CreateDefaultContext()
    q = talos_model.half_sitting.copy()
    index = feature.joint_names.index("arm_right_4_joint")
    joint = talos_model.plant.GetJointByName("arm_right_4_joint")
    lower, upper = joint.position_lower_limits()[0], joint.position_upper_limits()[0]
    for value, expected in ((lower, -1.0), (upper, 1.0), (0.5 * (lower + upper), 0.0)):
        q[joint.position_start()] = value
        feature.GetInputPort("state").FixValue(context, q)
        assert feature.GetOutputPort("error").Eval(context)[index] == pytest.approx(expected)
    assert "gripper_right_joint" in feature.joint_names and len(feature.joint_names) == 32


def test_posture_select_dof(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    posture = MetaTaskKinePosture(robot)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    e, J = feature_at(robot, posture.feature, context, talos_model.half_sitting)
    assert e.shape == (32,) and np.allclose(e, 0)  # joints only, at the reference
    posture.feature.selectDof(10, False, context)
    assert feature_at(robot, posture.feature, context, talos_model.half_sitting)[0].shape == (31,)
    with pytest.raises(InvalidInput):
        posture.feature.selectDof(99, True)
    posture.feature.selec("1", context)  # a short mask: the components it does not reach are unselected
    posture.feature.selectDof(12, True, context)
    assert parse_selection(posture.feature.settings(context).selection, talos_model.nv).tolist() == [0, 12]
