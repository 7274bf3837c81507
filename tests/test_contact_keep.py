"""A contact's return to its kept pose: ``J_C q̈ = −J̇_C v − K_v J_C v − K_p e`` with ``e`` the frame's
displacement from ``X_WC*`` (world; the rotation part ``½ vee(R R*ᵀ − R* Rᵀ)``), checked on the
entity's output for given kinematics, and on ``RobotDyn``'s contacts kept at the reference posture."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.systems.framework import DiagramBuilder

from sotdrake.dynamics.contact import Contact6d, pose_error
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.dynamics.terms import OpPointMotion
from sotdrake.exceptions import InvalidInput
from sotdrake.robots import load_talos


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("angle", [1e-4, 0.3, -1.0])
def test_the_rotation_error_is_the_axis_times_the_sine(axis, angle):
    kept = RigidTransform(RotationMatrix(RollPitchYaw(0.2, -0.4, 1.1)), [0.1, -0.2, 0.3])
    turn = np.zeros(3)
    turn[axis] = angle
    R = RotationMatrix(RollPitchYaw(*turn)) if axis == 0 else RotationMatrix.MakeYRotation(angle) if axis == 1 \
        else RotationMatrix.MakeZRotation(angle)
    pose = RigidTransform(R @ kept.rotation(), kept.translation() + [0.01, 0.0, -0.02])  # turned in world
    e = pose_error(pose, kept.rotation().matrix(), kept.translation())
    expected = np.zeros(3)
    expected[axis] = np.sin(angle)
    np.testing.assert_allclose(e[:3], expected, atol=1e-12)
    np.testing.assert_allclose(e[3:], [0.01, 0.0, -0.02], atol=1e-15)
    np.testing.assert_allclose(pose_error(kept, kept.rotation().matrix(), kept.translation()), 0.0, atol=1e-15)


@pytest.mark.parametrize("rectangle", [(-0.1, 0.1, -0.05, 0.05), None])
def test_the_reference_acceleration_returns_to_the_kept_pose(rectangle):
    nv, rng = 8, np.random.default_rng(3)
    contact = Contact6d("c", nv, rectangle)
    kept = RigidTransform(RotationMatrix(RollPitchYaw(0.1, 0.0, -0.3)), [0.2, 0.1, 0.0])
    contact.keep(kept)
    pose = RigidTransform(RotationMatrix(RollPitchYaw(0.1, 0.002, -0.3)), [0.2005, 0.1, -0.0003])
    motion = OpPointMotion(pose, rng.normal(size=(6, nv)), rng.normal(size=6), rng.normal(size=6))
    context = contact.CreateDefaultContext()
    contact.GetInputPort("kinematics").FixValue(context, AbstractValue.Make(motion))
    rows = slice(0, 6) if rectangle else slice(3, 6)
    e = pose_error(pose, kept.rotation().matrix(), kept.translation())[rows]
    without = -motion.drift[rows] - 30.0 * motion.velocity[rows]
    np.testing.assert_allclose(contact.GetOutputPort("contact").Eval(context).acceleration, without)  # K_p = 0: default
    contact.setPositionGain(225.0, context)
    got = contact.GetOutputPort("contact").Eval(context).acceleration
    np.testing.assert_allclose(got, without - 225.0 * e, rtol=1e-14, atol=1e-14)
    assert np.linalg.norm(e) > 1e-4  # (the term is really there)


def test_a_robot_contact_is_kept_at_the_reference_posture_and_bad_poses_are_refused():
    model = load_talos("reduced")
    robot = RobotDyn(DiagramBuilder(), model, "dynsimu", 1e-3)
    contact = robot.add_contact("contactLF", "left-sole")
    plant = model.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, model.half_sitting)
    X = plant.CalcRelativeTransform(context, plant.world_frame(), model.frame("left-sole"))
    R, p = contact.settings().kept
    np.testing.assert_allclose(R, X.rotation().matrix(), atol=1e-15)
    np.testing.assert_allclose(p, X.translation(), atol=1e-15)
    for bad in (None, np.eye(4), "here"):
        with pytest.raises(InvalidInput, match="keep"):
            contact.keep(bad)
    with pytest.raises(InvalidInput, match="kept position"):
        contact.keep(RigidTransform([np.nan, 0.0, 0.0]))
    assert contact.settings().kept[1] is p  # nothing changed


def test_a_position_gain_without_a_kept_pose_is_refused():
    contact = Contact6d("c", 8, None)
    with pytest.raises(InvalidInput, match="keep"):
        contact.setPositionGain(10.0)
    assert contact.settings().position_gain == 0.0
    contact.setPositionGain(0.0)  # (no gain: nothing to keep)
    contact.keep(RigidTransform())
    contact.setPositionGain(10.0)
    assert contact.settings().position_gain == 10.0
