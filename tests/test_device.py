"""The device integrates Drake's v held constant over each tick (q̇ = N(q) v), exactly."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake.configuration import Layout, difference, integrate
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


def test_constant_velocity_for_two_seconds(talos_model, rng):
    """Drake's v held constant: the base turns at ω_W about the world axes (R = exp([ω_W] t) R0) and
    its origin moves on a straight line (p = p0 + v_WBo t), exactly, over 2000 ticks."""
    from pydrake.systems.primitives import ConstantVectorSource

    plant = talos_model.plant
    nv = talos_model.nv
    w_W, v_W = np.array([0.4, -0.7, 0.25]), np.array([0.3, -0.1, 0.2])
    v = np.concatenate([w_W, v_W, 0.1 * rng.normal(size=nv - 6)])
    q0 = talos_model.half_sitting
    builder = DiagramBuilder()
    device = builder.AddSystem(Device(plant, 1e-3, q0))
    source = builder.AddSystem(ConstantVectorSource(v))
    builder.Connect(source.get_output_port(), device.GetInputPort("control"))
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(2.0 - 1e-4)  # ticks at 0, 1 ms, …, 1.999 s: 2000 ticks of 1 ms
    q = device.position(simulator.get_context())

    R0 = quaternion_wxyz_to_rotation(q0[:4])
    np.testing.assert_allclose(quaternion_wxyz_to_rotation(q[:4]), expm(2.0 * hat(w_W)) @ R0, atol=1e-9)
    np.testing.assert_allclose(q[4:7], q0[4:7] + 2.0 * v_W, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(q[:4]), 1.0, atol=1e-12)
    np.testing.assert_allclose(q[7:], q0[7:] + 2.0 * v[6:], atol=1e-9)
    # ⊕ is exact for a constant v: one step of 2 s lands where 2000 steps of 1 ms do.
    np.testing.assert_allclose(integrate(q0, v, 2.0, Layout.of(plant)), q, atol=1e-9)


def test_difference_inverts_integrate(talos_model, rng):
    layout = Layout.of(talos_model.plant)
    for _ in range(5):
        q = integrate(talos_model.half_sitting, rng.normal(size=talos_model.nv), 0.3, layout)
        delta = 0.05 * rng.normal(size=talos_model.nv)
        np.testing.assert_allclose(difference(integrate(q, delta, 1.0, layout), q, layout), delta, atol=1e-12)


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


def test_compiled_integration_equals_its_reference(talos_model, rng):
    """The compiled ``q ⊕ v·dt`` against :func:`python_integrate`: joints, base turns of every size
    (below the exponential's small-angle branch too), and wrong sizes refused."""
    from sotdrake.configuration import python_integrate
    from sotdrake.exceptions import InvalidInput

    layout = Layout.of(talos_model.plant)
    for _ in range(300):
        q = talos_model.half_sitting + 0.1 * rng.normal(size=talos_model.nq)
        q[:4] /= np.linalg.norm(q[:4])
        v = rng.normal(size=talos_model.nv) * rng.choice([1e-12, 1e-6, 1.0, 100.0])
        dt = float(rng.choice([1e-3, 0.1, 1.0]))
        np.testing.assert_allclose(integrate(q, v, dt, layout), python_integrate(q, v, dt, layout), rtol=0, atol=1e-15)
    with pytest.raises(InvalidInput, match="size"):
        integrate(q[:-1], v, 1e-3, layout)
    with pytest.raises(InvalidInput, match="size"):
        integrate(q, v[:-1], 1e-3, layout)
