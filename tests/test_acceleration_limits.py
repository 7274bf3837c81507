"""Joint acceleration limits in ``SolverKine``: ``|v − v_prev| ≤ a_max dt`` as hard bounds, with the
braking distance, so the bound set stays feasible; randomized runs never leave the bounds; a bad
``a_max`` is refused, changing nothing."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake import TALOS_GRIPPERS, InvalidInput, MetaTaskKine6d, Robot, add_sot, gotoNd, hold_feet_and_com
from sotdrake.scenarios import target_switch
from sotdrake.solvers.acceleration_limits import acceleration_bounds, braking_velocity


def test_braking_velocity_stops_before_the_limit_in_discrete_steps(rng):
    for _ in range(200):
        a, dt, d = 10.0 ** rng.uniform(-1, 3), 10.0 ** rng.uniform(-4, -2), 10.0 ** rng.uniform(-4, 0)
        v = float(braking_velocity(np.array([d]), np.array([a]), dt)[0])
        assert v * dt + v * v / (2 * a) == pytest.approx(d, rel=1e-9)  # the continuous bound, exactly
        travelled, speed = 0.0, v
        while speed > 0:  # this tick at v, then slower by a dt each tick
            travelled += speed * dt
            speed -= a * dt
        assert travelled <= d * (1 + 1e-12)
    assert braking_velocity(np.array([-1.0, 0.0]), np.array([5.0, 5.0]), 1e-3).tolist() == [0.0, 0.0]
    assert np.isinf(braking_velocity(np.array([1.0, np.inf]), np.array([np.inf, 5.0]), 1e-3)).all()


def test_the_bounds_are_ordered_and_keep_their_precedence(rng):
    for _ in range(2000):
        n = 5
        lower = rng.uniform(-3, 1, n)
        upper = lower + rng.uniform(0, 3, n)
        v_prev = rng.normal(scale=2, size=n)
        a = 10.0 ** rng.uniform(0, 3, n)
        brake_up, brake_lo = rng.uniform(-0.5, 3, n), -rng.uniform(-0.5, 3, n)
        lo, up = acceleration_bounds(lower, upper, v_prev, a, 1e-3, brake_lo, brake_up)
        assert np.all(lo <= up) and np.all(lower <= lo) and np.all(up <= upper)  # ordered, the limits first
        window = (np.maximum(lower, v_prev - a * 1e-3) <= np.minimum(upper, v_prev + a * 1e-3))
        assert np.all(lo[window] >= v_prev[window] - a[window] * 1e-3 - 1e-12)  # then the window, where it meets them
        assert np.all(up[window] <= v_prev[window] + a[window] * 1e-3 + 1e-12)
        everything = window & (np.maximum(lo, brake_lo) <= np.minimum(up, brake_up))
        assert np.all(up[everything] <= brake_up[everything]) and np.all(lo[everything] >= brake_lo[everything])


@pytest.mark.parametrize("seed", range(3))
def test_a_joint_driven_anywhere_never_leaves_its_limits_or_its_acceleration_bound(seed):
    """One joint, random velocity demands (often far beyond the bounds, towards the limits):
    starting at rest, the bound set is never empty, the joint never passes its limits and never
    changes speed by more than a dt."""
    from sotdrake.configuration import Layout
    from sotdrake.solvers.acceleration_limits import AccelerationBounds

    rng = np.random.default_rng(seed)
    layout = Layout(base_q=None, base_v=None, joints_q=np.array([0]), joints_v=np.array([0]))
    q_lo, q_hi, v_max, a, dt, margin = -1.0, 0.7, 3.0, 20.0, 1e-3, 1e-3
    bounds = AccelerationBounds(np.array([q_lo]), np.array([q_hi]), layout)
    q, v_prev = np.array([0.0]), np.zeros(1)
    for _ in range(5000):
        position_up = max((q_hi - margin - q[0]) / dt, min(0.0, (q_hi - q[0]) / dt))
        position_lo = min((q_lo + margin - q[0]) / dt, max(0.0, (q_lo - q[0]) / dt))
        l0, u0 = np.array([max(position_lo, -v_max)]), np.array([min(position_up, v_max)])
        lo, up = bounds(l0, u0, q, v_prev, np.array([a]), dt, margin)
        assert lo[0] <= up[0]
        v = np.clip(rng.choice([-1, 1]) * rng.uniform(0, 10, 1), lo, up)
        assert abs(v[0] - v_prev[0]) <= a * dt * (1 + 1e-9)
        q, v_prev = q + v * dt, v
        assert q_lo <= q[0] <= q_hi


def build_reach(model, dt=1e-3):
    builder = DiagramBuilder()
    robot = Robot(builder, model, dt)
    sot = add_sot(robot, solver="hqp")
    sot.setControlSelection(robot.velocity_selection(TALOS_GRIPPERS))
    hold_feet_and_com(robot, sot)
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    gotoNd(hand, (0.5, -0.2, 1.0), "111", 5.0)
    sot.push(hand.task)
    return robot, sot, hand, builder.Build()


def test_randomized_runs_keep_the_acceleration_bounds(talos_model, rng):
    """The hand sent to a new random target every 50 ms (a switch of the velocity the task asks
    for), 300 ticks: every joint's speed changes by at most a_max dt a tick, the joints stay within
    their limits, and no solve fails."""
    robot, sot, hand, diagram = build_reach(talos_model)
    a_max = 30.0
    sot.setAccelerationLimit(a_max)
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    own = sot.GetMyContextFromRoot(context)
    limits = robot.model.joint_limits()
    joints_v = sot.layout.joints_v
    joints_q = sot.layout.joints_q
    v_prev = np.zeros(robot.dimension)
    dt = robot.dt
    for tick in range(300):
        if tick % 50 == 0:
            gotoNd(hand, hand.current_pose(context).translation() + rng.uniform(-0.3, 0.3, 3), "111", rng.uniform(1, 20),
                   context=context)
        v = sot.GetOutputPort("control").Eval(own).copy()
        assert sot.GetOutputPort("diagnostics").Eval(own).failure == ""
        assert np.abs(v[joints_v] - v_prev[joints_v]).max() <= a_max * dt * (1 + 1e-6) + 1e-9, tick
        simulator.AdvanceTo((tick + 1) * dt)
        q = robot.device.position(context)
        assert np.all(q[joints_q] >= limits["position_lower"][joints_q] - 1e-9)
        assert np.all(q[joints_q] <= limits["position_upper"][joints_q] + 1e-9)
        v_prev = v
    assert np.abs(v_prev[joints_v]).max() > 0.05  # the robot did move


def test_acceleration_limits_are_checked_and_change_nothing(talos_model):
    robot, sot, hand, diagram = build_reach(talos_model)
    context = diagram.CreateDefaultContext()
    sot.setAccelerationLimit(50.0, context)
    before = sot.acceleration_limit(context)
    assert np.isinf(before[:6]).all() and (before[6:] == 50.0).all()  # the floating base is not bounded
    base_bounded = np.full(robot.dimension, 10.0)
    for bad in (0.0, -1.0, np.nan, "fast", True, np.ones(3), base_bounded, 1e7):
        with pytest.raises(InvalidInput, match="a_max"):
            sot.setAccelerationLimit(bad, context)
    np.testing.assert_array_equal(sot.acceleration_limit(context), before)
    assert sot.acceleration_limit() is None  # the defaults: TALOS' model has no acceleration limits
    sot.setAccelerationLimit(None, context)
    assert sot.acceleration_limit(context) is None


def test_the_target_switch_script_bounds_the_peak_acceleration(tmp_path):
    summary = target_switch.main(["--duration", "0.4", "--a-max", "25", "--out", str(tmp_path), "--quiet"])
    with_, without = summary["with"]["peak_joint_acceleration_rad_s2"], summary["without"]["peak_joint_acceleration_rad_s2"]
    assert max(with_.values()) <= 25.0 * (1 + 1e-6)
    assert min(without.values()) > 100.0  # without: the velocity jumps in one tick, at the start and at the switch
    assert (tmp_path / "summary.json").exists() and (tmp_path / "plots.png").exists()
