"""Manipulability: the Jacobian's derivative along each velocity direction and the gradient of
``μ = √det(J Jᵀ)`` against central finite differences on the manifold, on the small floating arm
and on TALOS; the inequality keeps the hand above its floor; unknown frames are refused."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import DiagramBuilder

from sotdrake import FrameNotFound, InvalidInput, MetaTaskKineManipulability, NotFound, Robot
from sotdrake.configuration import Layout, integrate
from sotdrake.features import manipulability_error_and_jacobian
from sotdrake.manipulability import jacobian_derivatives, manipulability, manipulability_and_gradient, upstream_coordinates
from tests.finite_differences import manifold_jacobian
from tests.test_feature_functions import Arm

RIGHT_ARM = [f"arm_right_{i}_joint" for i in range(1, 8)]


class Frame:
    def __init__(self, plant, frame: str, q0):
        self.plant, self.layout, self.q0 = plant, Layout.of(plant), q0
        self.context, self.frame, self.world = plant.CreateDefaultContext(), plant.GetFrameByName(frame), plant.world_frame()
        self.nv = plant.num_velocities()
        self.upstream = upstream_coordinates(plant)

    def jacobian_and_position(self, q):
        self.plant.SetPositions(self.context, q)
        J = self.plant.CalcJacobianSpatialVelocity(self.context, JacobianWrtVariable.kV, self.frame, np.zeros(3), self.world,
                                                   self.world)
        return J, self.plant.CalcRelativeTransform(self.context, self.world, self.frame).translation()

    def random_q(self, rng, scale=0.4):
        return integrate(self.q0, rng.normal(scale=scale, size=self.nv), 1.0, self.layout)


@pytest.fixture(scope="module", params=["arm", "talos"])
def frame(request, talos_model):
    if request.param == "arm":
        arm = Arm()
        return Frame(arm.plant, "l4", arm.plant.GetDefaultPositions())
    return Frame(talos_model.plant, "arm_right_7_link", talos_model.half_sitting)


def test_the_jacobians_derivative_is_its_finite_difference(frame, rng):
    q = frame.random_q(rng)
    J, p = frame.jacobian_and_position(q)
    derivatives = jacobian_derivatives(J, p, frame.upstream)
    h = 1e-6
    for k in range(frame.nv):
        step = np.eye(frame.nv)[k]
        numeric = (frame.jacobian_and_position(integrate(q, step, h, frame.layout))[0]
                   - frame.jacobian_and_position(integrate(q, step, -h, frame.layout))[0]) / (2 * h)
        np.testing.assert_allclose(derivatives[k], numeric, atol=1e-7 * max(1.0, np.abs(numeric).max()))


@pytest.mark.parametrize("rows", [np.array([3, 4, 5]), np.arange(6)])
def test_the_gradient_is_the_finite_difference_of_the_measure(frame, rng, rows):
    columns = None
    if frame.nv > 20:  # TALOS: the right arm's columns alone (the measure of that arm)
        columns = np.zeros(frame.nv, dtype=bool)
        for name in RIGHT_ARM:
            columns[frame.plant.GetJointByName(name).velocity_start()] = True
    for _ in range(3):
        q = frame.random_q(rng)
        mu, gradient = manipulability_and_gradient(*frame.jacobian_and_position(q), frame.upstream, rows, columns)
        numeric = manifold_jacobian(
            lambda q: np.array([manipulability_and_gradient(*frame.jacobian_and_position(q), frame.upstream, rows, columns)[0]]),
            q, frame.layout, frame.nv)[0]
        assert mu > 1e-3
        np.testing.assert_allclose(gradient, numeric, atol=1e-7 * max(1.0, np.abs(numeric).max()))
        e, J, e_dot = manipulability_error_and_jacobian(*frame.jacobian_and_position(q), frame.upstream, rows, columns)
        assert e[0] == mu and np.array_equal(J[0], gradient) and not e_dot.any()


def _jointed_plant(first: str):
    """A chain of boxes on ``first`` (a planar or roll-pitch-yaw floating joint to the world), then a
    universal joint, a roll-pitch-yaw ball joint and a revolute joint, the frame ``tip`` at its end."""
    from pydrake.math import RigidTransform
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import (
        BallRpyJoint,
        FixedOffsetFrame,
        PlanarJoint,
        RevoluteJoint,
        RpyFloatingJoint,
        SpatialInertia,
        UniversalJoint,
    )

    plant = MultibodyPlant(0.0)
    bodies = [plant.AddRigidBody(f"b{i}", SpatialInertia.SolidBoxWithMass(1.0, 0.1, 0.1, 0.3)) for i in range(4)]
    frames = [plant.AddFrame(FixedOffsetFrame(f"end{i}", body.body_frame(), RigidTransform([0.05, 0.1, 0.3])))
              for i, body in enumerate(bodies)]
    if first == "planar":
        plant.AddJoint(PlanarJoint("base", plant.world_frame(), bodies[0].body_frame(), np.zeros(3)))
    else:
        plant.AddJoint(RpyFloatingJoint("base", plant.world_frame(), bodies[0].body_frame()))
    plant.AddJoint(UniversalJoint("universal", frames[0], bodies[1].body_frame()))
    plant.AddJoint(BallRpyJoint("ball", frames[1], bodies[2].body_frame()))
    plant.AddJoint(RevoluteJoint("hinge", frames[2], bodies[3].body_frame(), [0.3, 0.0, 1.0]))
    plant.AddFrame(FixedOffsetFrame("tip", frames[3], RigidTransform()))
    plant.Finalize()
    return plant


@pytest.mark.parametrize("first", ["planar", "rpy_floating"])
def test_the_derivative_inside_planar_universal_ball_and_rpy_joints_is_its_finite_difference(first, rng):
    """Inside a planar joint its translations move its rotation's axis, inside a universal joint
    the first angle turns the second axis (and the floating joint's translations its rotations'):
    the derivative along each velocity, and the gradient, against finite differences along
    ``q̇ = N(q) v``."""
    plant = _jointed_plant(first)
    frame = Frame(plant, "tip", plant.GetDefaultPositions())
    context = plant.CreateDefaultContext()
    h = 1e-6
    for _ in range(3):
        q = rng.uniform(-0.6, 0.6, plant.num_positions())
        J, p = frame.jacobian_and_position(q)
        derivatives = jacobian_derivatives(J, p, frame.upstream)
        plant.SetPositions(context, q)
        for k in range(frame.nv):
            qdot = plant.MapVelocityToQDot(context, np.eye(frame.nv)[k])
            numeric = (frame.jacobian_and_position(q + h * qdot)[0] - frame.jacobian_and_position(q - h * qdot)[0]) / (2 * h)
            np.testing.assert_allclose(derivatives[k], numeric, atol=1e-7 * max(1.0, np.abs(numeric).max()))
        rows = np.array([3, 4, 5])
        mu, gradient = manipulability_and_gradient(J, p, frame.upstream, rows)
        for k in range(frame.nv):
            qdot = plant.MapVelocityToQDot(context, np.eye(frame.nv)[k])
            ahead, behind = (manipulability_and_gradient(*frame.jacobian_and_position(q + sign * h * qdot), frame.upstream, rows)[0]
                             for sign in (1.0, -1.0))
            assert gradient[k] == pytest.approx((ahead - behind) / (2 * h), abs=1e-7 * max(1.0, mu))


def test_the_measure_vanishes_at_a_singularity():
    J = np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0]])  # rank 1
    assert manipulability(J) == 0.0
    assert manipulability(np.eye(3)[:2]) == 1.0
    with pytest.raises(InvalidInput):
        manipulability(np.zeros((4, 3)))


@pytest.mark.parametrize("angle", [1e-4, 1e-7, 1e-9])
def test_the_measure_near_a_singularity_is_the_product_of_the_singular_values(angle, rng):
    """Through ``det(J Jᵀ)`` the round-off squared the condition number: 8.9e-9 for 3.9e-9."""
    U, V = np.linalg.qr(rng.normal(size=(2, 2)))[0], np.linalg.qr(rng.normal(size=(5, 5)))[0][:2]
    J = U @ np.diag([2.0, angle]) @ V
    assert manipulability(J) == pytest.approx(np.prod(np.linalg.svd(J, compute_uv=False)), rel=1e-6)


def test_the_floor_holds_on_a_stretching_arm_and_names_are_checked(talos_model):
    from pydrake.systems.analysis import Simulator

    from sotdrake import MetaTaskKine6d, add_sot, gotoNd, hold_feet_and_com

    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    sot = add_sot(robot, solver="hqp")
    with pytest.raises(FrameNotFound):
        MetaTaskKineManipulability("m", robot, "right-wristt", 0.01)
    with pytest.raises(NotFound):
        MetaTaskKineManipulability("m", robot, "right-wrist", 0.01, joints=["arm_right_9_joint"])
    with pytest.raises(InvalidInput, match="floor"):
        MetaTaskKineManipulability("m", robot, "right-wrist", -1.0)
    assert "featurem" not in robot._names  # nothing added by the refused ones
    hold_feet_and_com(robot, sot)
    floor = 0.01  # half-sitting: 0.019; stretched along the ball's direction without a floor: 1e-4
    manip = MetaTaskKineManipulability("manip", robot, "right-wrist", floor, joints=RIGHT_ARM)
    sot.push(manip.task)
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    gotoNd(hand, (-0.03, -1.25, 1.37), "111", (4.9, 0.9, 0.01, 0.9))  # beyond reach along the arm (sot-concept's)
    sot.push(hand.task)
    simulator = Simulator(builder.Build())
    context = simulator.get_mutable_context()
    lowest = np.inf
    for tick in range(1, 601):
        simulator.AdvanceTo(tick * 2e-3)
        lowest = min(lowest, manip.feature.GetOutputPort("error").Eval(manip.feature.GetMyContextFromRoot(context))[0])
    assert lowest >= floor * (1 - 1e-3)
    assert lowest < floor * 1.2  # the floor was reached: it is what stopped the arm
