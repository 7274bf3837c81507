"""The device integrates on SE(3) × R^n, consistently with Drake's velocity convention."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from sotdrake.configuration import Layout, integrate
from sotdrake.device import Device
from sotdrake.lie import hat, quaternion_wxyz_to_rotation
from tests.test_lie import expm


def test_integration_matches_drake_q_dot(talos_model, rng):
    """(q ⊕ v dt - q)/dt → Drake's MapVelocityToQDot(q, v): same coordinates, same frames."""
    plant, layout = talos_model.plant, Layout.of(talos_model.plant)
    context = plant.CreateDefaultContext()
    for _ in range(5):
        q = talos_model.half_sitting.copy()
        q[:4] = rng.normal(size=4)
        q[:4] /= np.linalg.norm(q[:4])
        v = rng.normal(size=talos_model.nv)
        plant.SetPositions(context, q)
        q_dot = plant.MapVelocityToQDot(context, v)
        dt = 1e-7
        np.testing.assert_allclose((integrate(q, v, dt, layout) - q) / dt, q_dot, atol=2e-6)


class BodyTwistSource(LeafSystem):
    """Drake v whose free-flyer part is the constant body twist (v_B, ω_B) at the current pose."""

    def __init__(self, nq, v_joints, v_B, w_B):
        super().__init__()
        self.q = self.DeclareVectorInputPort("q", nq)
        self.v_joints, self.v_B, self.w_B = v_joints, v_B, w_B
        self.DeclareVectorOutputPort("v", 6 + len(v_joints), self._calc)

    def _calc(self, context, output: BasicVector):
        R = quaternion_wxyz_to_rotation(self.q.Eval(context)[:4])
        output.SetFromVector(np.concatenate([R @ self.w_B, R @ self.v_B, self.v_joints]))


def test_constant_velocity_for_two_seconds(talos_model, rng):
    plant = talos_model.plant
    nv = talos_model.nv
    v_B, w_B = np.array([0.3, -0.1, 0.2]), np.array([0.4, -0.7, 0.25])
    v_joints = 0.1 * rng.normal(size=nv - 6)
    q0 = talos_model.half_sitting
    builder = DiagramBuilder()
    device = builder.AddSystem(Device(plant, 1e-3, q0))
    source = builder.AddSystem(BodyTwistSource(talos_model.nq, v_joints, v_B, w_B))
    builder.Connect(device.GetOutputPort("state"), source.get_input_port())
    builder.Connect(source.get_output_port(), device.GetInputPort("control"))
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(2.0 - 1e-4)  # ticks at 0, 1 ms, …, 1.999 s: 2000 ticks of 1 ms
    q = device.position(simulator.get_context())

    twist = np.zeros((4, 4))
    twist[:3, :3], twist[:3, 3] = hat(w_B), v_B
    X0 = np.eye(4)
    X0[:3, :3], X0[:3, 3] = quaternion_wxyz_to_rotation(q0[:4]), q0[4:7]
    X = X0 @ expm(2.0 * twist)
    np.testing.assert_allclose(quaternion_wxyz_to_rotation(q[:4]), X[:3, :3], atol=1e-9)
    np.testing.assert_allclose(q[4:7], X[:3, 3], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(q[:4]), 1.0, atol=1e-12)
    np.testing.assert_allclose(q[7:], q0[7:] + 2.0 * v_joints, atol=1e-9)
    # Not the naive R³ × SO(3) flow of a constant world velocity: the test can tell them apart.
    assert np.linalg.norm(q[4:7] - (q0[4:7] + 2.0 * X0[:3, :3] @ v_B)) > 1e-2
    # ⊕ is exact for a constant body twist: one step of 2 s lands where 2000 steps of 1 ms do.
    R0 = quaternion_wxyz_to_rotation(q0[:4])
    one_step = integrate(q0, np.concatenate([R0 @ w_B, R0 @ v_B, v_joints]), 2.0, Layout.of(plant))
    np.testing.assert_allclose(one_step, q, atol=1e-9)


def test_device_never_clamps_and_reports_a_limit_crossing(talos_model, caplog):
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    joint = talos_model.plant.GetJointByName("gripper_right_joint")  # starts on its upper limit 0
    v = np.zeros(talos_model.nv)
    v[joint.velocity_start()] = 0.5
    builder = DiagramBuilder()
    device = builder.AddSystem(Device(talos_model.plant, 1e-3, talos_model.half_sitting))
    source = builder.AddSystem(ConstantVectorSource(v))
    builder.Connect(source.get_output_port(), device.GetInputPort("control"))
    simulator = Simulator(builder.Build())
    with caplog.at_level("WARNING", logger="sotdrake.device"):
        simulator.AdvanceTo(0.0105)
    q = device.position(simulator.get_context())
    assert q[joint.position_start()] == pytest.approx(0.5 * 11e-3)  # integrated, not clamped
    crossings = [r for r in caplog.records if "gripper_right_joint" in r.getMessage()]
    assert len(crossings) == 1  # reported once, when it crossed
