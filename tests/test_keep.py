"""``keep()`` holds the pose the diagram's own kinematics gives the feature in that context.

In the closed-loop physics diagram the SoT's kinematics reads the simulated robot's joints, not the
device's ``q``: after the right elbow of the simulated robot is moved by 0.3 rad, the device still
holds half-sitting, and a pose computed at the device's ``q`` would be ~8.5 cm from the one the
feature sees.
"""

import numpy as np
import pytest

from sotdrake.exceptions import InvalidInput
from sotdrake.scenarios import talos_physics


@pytest.fixture(scope="module")
def closed_loop():
    physics = talos_physics
    run = physics.build_diagram("stand", loop="closed")
    context = run.diagram.CreateDefaultContext()
    plant = run.physical.plant
    plant_context = plant.GetMyMutableContextFromRoot(context)
    elbow = plant.GetJointByName("arm_right_4_joint")
    q = plant.GetPositions(plant_context)
    q[elbow.position_start()] += 0.3
    plant.SetPositions(plant_context, q)
    return run, context


def _feature_error(meta, context):
    return meta.feature.GetOutputPort("error").Eval(meta.feature.GetMyContextFromRoot(context))


def test_keep_holds_the_pose_the_feature_sees(closed_loop):
    run, context = closed_loop
    taskRH = run.taskRH
    q_device = run.robot.device.position(context)
    side = taskRH.dyn.pose_at(taskRH.opPoint, q_device).multiply(taskRH.opmodif)
    seen = taskRH.current_pose(context)
    # the moved elbow is seen: the device's q would give another pose
    assert np.linalg.norm(seen.translation() - side.translation()) > 0.05
    taskRH.keep(context)
    held = taskRH.featureDes.settings(context).position
    np.testing.assert_allclose(held.GetAsMatrix4(), seen.GetAsMatrix4(), atol=1e-12)
    np.testing.assert_allclose(_feature_error(taskRH, context), 0.0, atol=1e-12)


def test_keep_of_the_com_and_the_error_is_zero(closed_loop):
    run, context = closed_loop
    taskCom = run.taskCom
    before = np.linalg.norm(_feature_error(taskCom, context))
    taskCom.keep(context)
    assert before > 1e-4  # the elbow moved the CoM away from the build-time reference
    np.testing.assert_allclose(_feature_error(taskCom, context), 0.0, atol=1e-12)


def test_keep_needs_the_root_context(closed_loop):
    run, context = closed_loop
    own = run.taskRH.featureDes.GetMyContextFromRoot(context)
    before = run.taskRH.featureDes.settings(context).position.GetAsMatrix4()
    with pytest.raises(InvalidInput, match="root diagram context"):
        run.taskRH.keep(own)
    np.testing.assert_array_equal(run.taskRH.featureDes.settings(context).position.GetAsMatrix4(), before)


def test_a_context_given_to_keep_is_freed_with_its_last_reference(closed_loop):
    """``keep()`` stores a copy of the pose it reads: a pose read from a port refers into the Context
    it was read from and keeps it alive, so settings holding it would keep their own Context, with
    all its caches, alive through a cycle Python's collector cannot see (a leak per context)."""
    import gc

    from sotdrake.entity import _Frozen

    run, _ = closed_loop

    def live_settings() -> int:
        gc.collect()
        return sum(isinstance(o, _Frozen) for o in gc.get_objects())

    before = live_settings()
    for _ in range(3):
        context = run.diagram.CreateDefaultContext()
        run.taskRH.feature.setOpmodif(None, context)  # the pose read as it is (an opmodif makes a new one)
        run.taskRH.keep(context)
        run.taskCom.keep(context)
        del context
    assert live_settings() == before


def test_current_pose_is_a_value_not_a_view_into_the_context(closed_loop):
    """The pose ``current_pose`` returned stays as it was when the robot moves: a pose read from a
    port refers into the Context's cache, which the next evaluation overwrites."""
    run, _ = closed_loop
    context = run.diagram.CreateDefaultContext()
    run.taskRH.feature.setOpmodif(None, context)  # the pose read as it is (an opmodif makes a new one)
    X = run.taskRH.current_pose(context)
    held = X.GetAsMatrix4()
    plant = run.physical.plant
    plant_context = plant.GetMyMutableContextFromRoot(context)
    q = plant.GetPositions(plant_context)
    q[plant.GetJointByName("arm_right_4_joint").position_start()] += 0.3
    plant.SetPositions(plant_context, q)
    moved = run.taskRH.current_pose(context)
    assert np.linalg.norm(moved.translation() - held[:3, 3]) > 0.05  # the hand did move
    np.testing.assert_array_equal(X.GetAsMatrix4(), held)
