"""Every feature's Jacobian against finite differences, through the diagram's own systems,
at random TALOS configurations, stepping q on the manifold (q ⊕ h·δv)."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import DiagramBuilder

from sotdrake.configuration import Layout
from sotdrake.lie import exp_so3
from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom
from sotdrake.robot import Robot
from tests.conftest import random_configuration
from tests.finite_differences import manifold_jacobian


@pytest.fixture(scope="module")
def rig(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    tasks = {
        "rh_desired": MetaTaskKine6d("rh", robot, "rh", "right-wrist"),
        "rh_current": MetaTaskKine6d("rhc", robot, "rh", "right-wrist"),
        "lf_xy_yaw": MetaTaskKine6d("lf", robot, "lf", "left-ankle"),
        "gaze": MetaTaskKine6d("gaze", robot, "gaze", "gaze"),
        "com": MetaTaskKineCom(robot),
    }
    offset = RigidTransform(RotationMatrix(exp_so3(np.array([0.3, -0.2, 0.5]))), [0.1, 0.02, -0.05])
    tasks["rh_desired"].opmodif = offset
    tasks["rh_current"].opmodif = offset
    tasks["rh_current"].feature.frame("current")
    tasks["lf_xy_yaw"].feature.selec("100011")
    tasks["com"].feature.selec("011")
    diagram = builder.Build()
    return robot, tasks, diagram


def feature_at(robot, feature, context, q):
    robot.device.set_position(context, q)
    own = feature.GetMyContextFromRoot(context)
    return feature.GetOutputPort("error").Eval(own).copy(), feature.GetOutputPort("jacobian").Eval(own).copy()


@pytest.mark.parametrize("name", ["rh_desired", "rh_current", "lf_xy_yaw", "gaze", "com"])
@pytest.mark.parametrize("seed", range(3))
def test_feature_jacobian_by_finite_differences(rig, name, seed):
    robot, tasks, diagram = rig
    rng = np.random.default_rng(seed)
    model, layout = robot.model, Layout.of(robot.model.plant)
    context = diagram.CreateDefaultContext()
    q = random_configuration(model, rng)
    task = tasks[name]
    if name != "com":  # a desired pose away from the current one (rotation < 2 rad)
        robot.device.set_position(context, q)
        X = task.current_pose(context)
        turn = RotationMatrix(exp_so3(rng.uniform(-1, 1, 3)))
        task.featureDes.setPosition(RigidTransform(X.rotation().multiply(turn), X.translation() + rng.normal(scale=0.2, size=3)), context)
    else:
        task.featureDes.setReference(robot.dynamic.com_at(q) + rng.normal(scale=0.1, size=3), context)
    e, J = feature_at(robot, task.feature, context, q)
    assert np.linalg.norm(e) > 1e-2  # not a trivial point
    numeric = manifold_jacobian(lambda q: feature_at(robot, task.feature, context, q)[0], q, layout, model.nv)
    np.testing.assert_allclose(J, numeric, atol=1e-6 * max(1.0, np.abs(J).max()))


def test_selection_masks_pick_the_documented_rows(rig):
    robot, tasks, diagram = rig
    context = diagram.CreateDefaultContext()
    e_lf, J_lf = feature_at(robot, tasks["lf_xy_yaw"].feature, context, robot.model.half_sitting)
    e_com, _ = feature_at(robot, tasks["com"].feature, context, robot.model.half_sitting)
    assert J_lf.shape == (3, robot.model.nv) and e_lf.shape == (3,)  # '100011': X, Y and RZ
    assert e_com.shape == (2,)  # '011': X and Y


def test_frame_desired_translation_error_is_world_difference(rig):
    """With R* = I, frame('desired') gives e = p - p* in world axes: the sign and the frame."""
    robot, tasks, diagram = rig
    context = diagram.CreateDefaultContext()
    task = tasks["rh_desired"]
    p = task.current_pose(context).translation()
    task.featureDes.setPosition(p - np.array([0.1, -0.2, 0.3]), context)
    task.feature.selec("111", context)
    e, _ = feature_at(robot, task.feature, context, robot.model.half_sitting)
    np.testing.assert_allclose(e, [0.1, -0.2, 0.3], atol=1e-12)


@pytest.mark.parametrize("frame", ["desired", "current"])
def test_translation_only_path_matches_the_full_one(frame, rng):
    from sotdrake.features import pose_error_and_jacobian

    X = RigidTransform(RotationMatrix(exp_so3(rng.normal(size=3))), rng.normal(size=3))
    Xd = RigidTransform(RotationMatrix(exp_so3(rng.normal(size=3))), rng.normal(size=3))
    J, V = rng.normal(size=(6, 10)), rng.normal(size=6)
    full = pose_error_and_jacobian(X, J, Xd, frame, V)
    fast = pose_error_and_jacobian(X, J, Xd, frame, V, rows=np.array([0, 1, 2]))  # no logarithm taken
    for a, b in zip(full, fast, strict=False):
        np.testing.assert_allclose(a[:3], b, atol=1e-14)
