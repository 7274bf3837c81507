"""Each feature's pure function ``…_error_and_jacobian`` against finite differences on a small
floating-base model (a free base and a 4-joint arm, nq 11, nv 10), stepping on the manifold with
the one shared helper; ``errordot`` against a moving reference."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable

from sotdrake.configuration import Layout, integrate
from sotdrake.exceptions import InvalidInput
from sotdrake.features import (
    feature1d_error_and_jacobian,
    generic_error_and_jacobian,
    joint_limits_error_and_jacobian,
    pose_error_and_jacobian,
    posture_error_and_jacobian,
    relative_pose_error_and_jacobian,
    visual_point_error_and_jacobian,
)
from sotdrake.features.feature6d import python_pose_error_and_jacobian
from sotdrake.features.posture import joint_rows
from sotdrake.lie import exp_so3
from tests.finite_differences import manifold_jacobian

LINK = ('<link name="{0}"><inertial><mass value="{1}"/><origin xyz="0 0 0.1"/>'
        '<inertia ixx="0.01" iyy="0.02" izz="0.03" ixy="0" ixz="0" iyz="0"/></inertial></link>')
JOINT = ('<joint name="j{0}" type="revolute"><parent link="l{1}"/><child link="l{0}"/><origin xyz="0.05 0.1 0.2" rpy="0.3 -0.2 0.1"/>'
         '<axis xyz="{2}"/><limit lower="-2" upper="{3}" effort="1" velocity="1"/></joint>')
AXES = ["0 0 1", "0 1 0", "1 0 0", "0 0.6 0.8"]
URDF = ('<robot name="arm">' + LINK.format("l0", 3.0)
        + "".join(LINK.format(f"l{i}", 1.0 + 0.2 * i) + JOINT.format(i, i - 1, AXES[i - 1], 1.5 + 0.1 * i) for i in range(1, 5))
        + "</robot>")


class Arm:
    """A floating base ``l0`` and four revolute joints; poses and Jacobians from Drake."""

    def __init__(self):
        self.plant = MultibodyPlant(0.0)
        Parser(self.plant).AddModelsFromString(URDF, "urdf")
        self.plant.Finalize()
        self.context = self.plant.CreateDefaultContext()
        self.layout = Layout.of(self.plant)
        self.nq, self.nv = self.plant.num_positions(), self.plant.num_velocities()
        self.world = self.plant.world_frame()

    def at(self, q):
        self.plant.SetPositions(self.context, q)
        return self

    def pose(self, q, frame: str) -> np.ndarray:
        return self.at(q).plant.CalcRelativeTransform(self.context, self.world, self.plant.GetFrameByName(frame)).GetAsMatrix4()

    def jacobian(self, q, frame: str) -> np.ndarray:
        return self.at(q).plant.CalcJacobianSpatialVelocity(
            self.context, JacobianWrtVariable.kV, self.plant.GetFrameByName(frame), np.zeros(3), self.world, self.world)

    def com(self, q):
        return self.at(q).plant.CalcCenterOfMassPositionInWorld(self.context)

    def com_jacobian(self, q):
        return self.at(q).plant.CalcJacobianCenterOfMassTranslationalVelocity(self.context, JacobianWrtVariable.kV, self.world, self.world)

    def random_q(self, rng):
        q = self.plant.GetDefaultPositions()
        q = integrate(q, rng.normal(size=self.nv), 1.0, self.layout)
        return np.clip(q, self.plant.GetPositionLowerLimits(), self.plant.GetPositionUpperLimits())


@pytest.fixture(scope="module")
def arm():
    return Arm()


def random_pose(rng, scale=1.0) -> np.ndarray:
    return RigidTransform(RotationMatrix(exp_so3(rng.uniform(-scale, scale, 3))), rng.normal(size=3)).GetAsMatrix4()


def check(f, q, arm, J, atol=1e-6):
    numeric = manifold_jacobian(f, q, arm.layout, arm.nv)
    np.testing.assert_allclose(J, numeric, atol=atol * max(1.0, np.abs(J).max()))


@pytest.mark.parametrize("frame", ["desired", "current"])
@pytest.mark.parametrize("opmodif", [False, True])
@pytest.mark.parametrize("rows", [None, (0, 1, 2), (0, 1, 5)])
@pytest.mark.parametrize("seed", range(2))
def test_pose(arm, frame, opmodif, rows, seed):
    rng = np.random.default_rng(seed)
    q = arm.random_q(rng)
    X_OpF = random_pose(rng, 0.5) if opmodif else None
    X_d = random_pose(rng)
    rows = None if rows is None else np.array(rows)

    def f(q):
        return pose_error_and_jacobian(arm.pose(q, "l4"), arm.jacobian(q, "l4"), X_d, frame, None, X_OpF, rows)

    e, J, e_dot = f(q)
    assert np.linalg.norm(e) > 1e-2 and not e_dot.any()
    check(lambda q: f(q)[0], q, arm, J)


@pytest.mark.parametrize("frame", ["desired", "current"])
def test_pose_errordot_by_moving_the_target(arm, frame, rng):
    q = arm.random_q(rng)
    X, J_WF, X_d = arm.pose(q, "l3"), arm.jacobian(q, "l3"), random_pose(rng)
    V = rng.normal(size=6)  # (ω*, ṗ*), world

    def moved(s):
        X_s = X_d.copy()
        X_s[:3, :3] = exp_so3(V[:3] * s) @ X_d[:3, :3]
        X_s[:3, 3] += V[3:] * s
        return pose_error_and_jacobian(X, J_WF, X_s, frame)[0]

    h = 1e-6
    np.testing.assert_allclose(pose_error_and_jacobian(X, J_WF, X_d, frame, V)[2], (moved(h) - moved(-h)) / (2 * h), atol=1e-6)



def _rotation_by(rng, angle: float) -> np.ndarray:
    axis = rng.normal(size=3)
    return exp_so3(angle * axis / np.linalg.norm(axis))


def test_compiled_pose_error_is_the_python_reference(rng):
    """The compiled 6D error against its Python reference, both frames, with and without opmodif,
    a moving target and a selection, rotation errors near 0 and near π (the logarithm's branches),
    column-major (Drake's) and C-ordered matrices, any number of columns."""
    angles = [0.0, 1e-9, 1e-5, 0.5, 2.0, np.pi - 3e-5, np.pi - 1e-7, np.pi]
    rows_choices = [None, np.array([0, 1, 2]), np.array([3, 4, 5]), np.array([0, 2, 4]), np.array([5])]
    for trial in range(600):
        X = random_pose(rng)
        X_d = X.copy()
        X_d[:3, :3] = X[:3, :3] @ _rotation_by(rng, angles[trial % len(angles)])
        X_d[:3, 3] += rng.normal(size=3)
        J = rng.normal(size=(6, 1 + trial % 40))
        if trial % 2:
            X, J = np.asfortranarray(X), np.asfortranarray(J)
        args = (X, J, X_d, ("desired", "current")[trial % 3 % 2], rng.normal(size=6) if trial % 4 else None,
                random_pose(rng, 0.5) if trial % 5 == 0 else None, rows_choices[trial % len(rows_choices)])
        for compiled, reference in zip(pose_error_and_jacobian(*args), python_pose_error_and_jacobian(*args), strict=True):
            assert compiled.shape == reference.shape
            np.testing.assert_allclose(compiled, reference, rtol=1e-12, atol=1e-12)


def test_compiled_pose_error_refuses_bad_arguments():
    X, J = np.eye(4), np.zeros((6, 3))
    with pytest.raises(InvalidInput, match="frame"):
        pose_error_and_jacobian(X, J, X, "world")
    with pytest.raises(InvalidInput, match="6×nv"):
        pose_error_and_jacobian(X, np.zeros((3, 3)), X)
    with pytest.raises(InvalidInput, match="rows"):
        pose_error_and_jacobian(X, J, X, rows=np.zeros(0, dtype=int))
    for rows in ([0, 6], [4, 0], [5, 5, 2]):  # (out of range, not increasing: the rotation rows would be skipped)
        with pytest.raises(InvalidInput, match="increasing indices"):
            pose_error_and_jacobian(X, J, X, rows=np.array(rows))
    with pytest.raises(InvalidInput, match="4×4"):
        pose_error_and_jacobian(np.eye(3), J, X)
    with pytest.raises(InvalidInput, match="6-vector"):
        pose_error_and_jacobian(X, J, X, V_WFd=np.zeros(3))

def test_generic_on_the_com(arm, rng):
    q, target, velocity = arm.random_q(rng), rng.normal(size=3), rng.normal(size=3)
    e, J, e_dot = generic_error_and_jacobian(arm.com(q), arm.com_jacobian(q), target, velocity)
    np.testing.assert_allclose(e_dot, -velocity)
    check(lambda q: generic_error_and_jacobian(arm.com(q), arm.com_jacobian(q), target)[0], q, arm, J)
    e2, J2, _ = generic_error_and_jacobian(arm.com(q), arm.com_jacobian(q), target, None, np.array([0, 2]))
    np.testing.assert_array_equal(e2, e[[0, 2]])
    np.testing.assert_array_equal(J2, J[[0, 2]])


@pytest.mark.parametrize("seed", range(3))
def test_posture_with_the_free_base(arm, seed):
    rng = np.random.default_rng(seed)
    q, q_star = arm.random_q(rng), arm.random_q(rng)
    v_star = np.zeros(arm.nv)
    e, J, _ = posture_error_and_jacobian(q, q_star, v_star, arm.layout)
    check(lambda q: posture_error_and_jacobian(q, q_star, v_star, arm.layout)[0], q, arm, J)


def test_posture_joint_rows_are_the_full_functions_rows(arm, rng):
    """The joints-only fast path (the posture's default selection) returns the selected rows of
    the full function, whatever their order in q and v."""
    q, q_star, v_star = arm.random_q(rng), arm.random_q(rng), rng.normal(size=arm.nv)
    joint_q = np.full(arm.nv, -1)
    joint_q[arm.layout.joints_v] = arm.layout.joints_q
    full = posture_error_and_jacobian(q, q_star, v_star, arm.layout)
    for rows in (arm.layout.joints_v, arm.layout.joints_v[::2], arm.layout.joints_v[-1:]):
        for part, whole in zip(joint_rows(q, q_star, v_star, joint_q, rows), full, strict=True):
            np.testing.assert_array_equal(part, whole[rows])


def test_posture_errordot_by_moving_the_reference(arm, rng):
    q, q_star, v_star = arm.random_q(rng), arm.random_q(rng), rng.normal(size=arm.nv)
    h = 1e-6
    moved = [posture_error_and_jacobian(q, integrate(q_star, v_star, s, arm.layout), v_star, arm.layout)[0] for s in (h, -h)]
    e_dot = posture_error_and_jacobian(q, q_star, v_star, arm.layout)[2]
    np.testing.assert_allclose(e_dot, (moved[0] - moved[1]) / (2 * h), atol=1e-6)


def test_joint_limits(arm, rng):
    lower, upper = arm.plant.GetPositionLowerLimits(), arm.plant.GetPositionUpperLimits()
    q_index, v_index = arm.layout.joints_q, arm.layout.joints_v
    args = (q_index, v_index, lower[q_index], (upper - lower)[q_index], arm.nv)
    q = arm.random_q(rng)
    e, J, _ = joint_limits_error_and_jacobian(q, *args)
    assert np.all(np.abs(e) <= 1)
    check(lambda q: joint_limits_error_and_jacobian(q, *args)[0], q, arm, J)


def test_feature1d_of_a_pose(arm, rng):
    q, X_d = arm.random_q(rng), random_pose(rng)

    def inner(q):
        return pose_error_and_jacobian(arm.pose(q, "l4"), arm.jacobian(q, "l4"), X_d)

    e, J, _ = feature1d_error_and_jacobian(*inner(q))
    check(lambda q: feature1d_error_and_jacobian(*inner(q))[0], q, arm, J)


def test_relative_pose(arm, rng):
    q, X_BAd = arm.random_q(rng), random_pose(rng)

    def f(q):
        return relative_pose_error_and_jacobian(arm.pose(q, "l4"), arm.jacobian(q, "l4"), arm.pose(q, "l1"), arm.jacobian(q, "l1"), X_BAd)

    check(lambda q: f(q)[0], q, arm, f(q)[1])


def test_relative_pose_errordot_is_the_derivative_along_the_references_motion(arm, rng):
    """The desired relative pose moving at ``(ω*, ṗ*)`` in B's axes (``R* ← exp([ω*]× s) R*``,
    ``p* ← p* + s ṗ*``): ``ė_ref`` is the central difference of ``e`` (it was 0)."""

    for _ in range(5):
        q, X_BAd, V = arm.random_q(rng), random_pose(rng), rng.normal(size=6)
        poses = (arm.pose(q, "l4"), arm.jacobian(q, "l4"), arm.pose(q, "l1"), arm.jacobian(q, "l1"))
        h, moved = 1e-6, []
        for step in (h, -h):
            X = X_BAd.copy()
            X[:3, :3], X[:3, 3] = exp_so3(V[:3] * step) @ X_BAd[:3, :3], X_BAd[:3, 3] + step * V[3:]
            moved.append(relative_pose_error_and_jacobian(*poses, X)[0])
        e_dot = relative_pose_error_and_jacobian(*poses, X_BAd, V)[2]
        np.testing.assert_allclose(e_dot, (moved[0] - moved[1]) / (2 * h), atol=1e-6)
        assert not relative_pose_error_and_jacobian(*poses, X_BAd)[2].any()


def test_visual_point(arm, rng):
    q = arm.random_q(rng)
    X_WC = arm.pose(q, "l4")
    point = X_WC[:3, :3] @ np.array([0.1, -0.2, 1.5]) + X_WC[:3, 3]  # in front of the camera (z forward)
    desired, velocity = np.array([0.05, -0.02]), rng.normal(size=3)

    def f(q):
        return visual_point_error_and_jacobian(arm.pose(q, "l4"), arm.jacobian(q, "l4"), point, desired)

    check(lambda q: f(q)[0], q, arm, f(q)[1])
    h = 1e-6
    moved = [visual_point_error_and_jacobian(X_WC, arm.jacobian(q, "l4"), point + s * velocity, desired)[0] for s in (h, -h)]
    e_dot = visual_point_error_and_jacobian(X_WC, arm.jacobian(q, "l4"), point, desired, velocity)[2]
    np.testing.assert_allclose(e_dot, (moved[0] - moved[1]) / (2 * h), atol=1e-7)
