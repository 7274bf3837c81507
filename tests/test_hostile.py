"""Nothing breaks the process, nothing drifts, nothing is silently accepted (a fast subset of
``bench/hostile.py``, plus the checks of each fix)."""

import logging

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from sotdrake.exceptions import InvalidInput, RobotDescriptionError, SotError
from tests.hostile import CONTACT_TOLERANCE, bad_input_solver, bad_inputs, run_attempts


def test_the_harness_catches_a_process_exit():
    """An attempt that aborts or exits the process is recorded as such, and the next one still runs."""
    results = run_attempts("crash", "cascade", [0, 1], timeout=60.0)
    assert results[0]["status"] == "process_exit" and results[0]["returncode"] != 0
    assert results[1]["status"] == "process_exit" and results[1]["returncode"] == 3


def test_bad_inputs_raise_a_sot_error_and_change_nothing():
    """Every 12th case of the table (the full table: bench/hostile.py)."""
    table = bad_inputs()
    assert len(table) >= 300
    chosen = list(range(0, len(table), 12))
    results = {}
    for solver in ("cascade", "hqp"):
        indices = [i for i in chosen if bad_input_solver(table[i][0]) == solver]
        results.update(run_attempts("bad", solver, indices))
    failures = {table[i][0]: r for i, r in results.items() if r.get("status") != "sot_error" or not r.get("unchanged")}
    assert not failures
    assert len(results) == len(chosen)


@pytest.mark.parametrize("solver,dt,seeds", [("cascade", 1e-3, [0, 2, 4]), ("hqp", 1e-3, [2, 4]),
                                               ("cascade", 5e-3, [2, 10]), ("hqp", 5e-3, [10, 14]), ("hqp", 10e-3, [4])])
def test_randomized_runs_keep_the_contacts(solver, dt, seeds):
    """Random stacks under the contacts, targets up to 5 m away, gains up to λ·dt = 1.9, 60 ticks at
    1, 5 and 10 ms: finite, the ankles within 0.1 mm at every tick (the step limit, whose seeds
    here drifted by 0.3 to 0.6 mm without it), no frozen tick, no joint past its limits under
    SolverKine."""
    results = run_attempts("random", solver, seeds, duration=60 * dt, dt=dt)
    assert sorted(results) == seeds
    for seed, run in results.items():
        assert run.get("error") is None and run.get("finite"), (seed, run)
        assert run["dt"] == dt and run["time"] >= 60 * dt - 1e-9
        assert run["contact_drift_m"] <= CONTACT_TOLERANCE, (seed, run)
        assert run["frozen_ticks"] == 0, (seed, run)
        if solver == "hqp":
            assert run["limit_violation"] <= 1e-9, (seed, run)


def test_a_worker_is_recycled_after_its_share_of_attempts():
    """Three attempts with one per worker: three processes, every result there."""
    results = run_attempts("random", "cascade", [0, 1, 2], duration=0.005, per_worker=1)
    assert sorted(results) == [0, 1, 2] and all(r.get("finite") for r in results.values())


# --- item 1: the velocity scaling and the curvature correction ---------------------------------
def test_velocity_scale_is_uniform_and_keeps_a_held_level():
    from sotdrake.solvers import solve_cascade
    from sotdrake.solvers.velocity_scaling import scale_to_limits, velocity_scale

    assert velocity_scale(np.array([1.0, -2.0]), np.array([2.0, 2.0])) == 1.0
    v, s = scale_to_limits(np.array([4.0, -1.0]), np.array([2.0, 2.0]))
    assert s == 0.5 and np.allclose(v, [2.0, -0.5])
    # A held level (ė* = 0) above a near-singular one: the huge velocity is brought down, the held
    # level still gets J v = 0.
    rng = np.random.default_rng(1)
    J1, J2 = rng.normal(size=(2, 6)), rng.normal(size=(1, 6))
    J2 = J2 - 1e-3 * rng.normal(size=(1, 6))
    J2[0, :] = J1[0] + 1.5e-4 * rng.normal(size=6)  # almost in the held level's row space
    result = solve_cascade([(J1, np.zeros(2)), (J2, np.array([1.0]))], 6, svd_threshold=1e-6)
    assert np.abs(result.velocity).max() > 100.0
    v, s = scale_to_limits(result.velocity, np.full(6, 5.0))
    assert np.abs(v).max() == pytest.approx(5.0) and np.abs(J1 @ v).max() < 1e-9


def test_velocity_bounds_of_the_floating_base(talos_model):
    from sotdrake.configuration import Layout
    from sotdrake.solvers.limits import velocity_bounds

    limits = talos_model.joint_limits()
    args = (talos_model.half_sitting, limits["position_lower"], limits["position_upper"],
            limits["velocity_lower"], limits["velocity_upper"], 1e-3, 1e-3, Layout.of(talos_model.plant))
    lower, upper = velocity_bounds(*args)
    assert np.isinf(upper[:6]).all()
    lower, upper = velocity_bounds(*args, base_velocity=(2.0, 3.0))
    assert np.array_equal(upper[:6], [2, 2, 2, 3, 3, 3]) and np.array_equal(lower[:6], [-2, -2, -2, -3, -3, -3])


def test_solver_kine_bounds_the_base_without_contact():
    """No contact, a CoM task 50 m away with the largest gain: the base stays within its bound (it
    reached 1.5e15 m/s before the bound)."""
    from pydrake.systems.analysis import Simulator

    from sotdrake.meta_tasks import MetaTaskKineCom, gotoNd
    from sotdrake.robot import add_sot, talos
    from sotdrake.solvers.base_velocity import default_base_velocity_limit

    builder = DiagramBuilder()
    robot = talos(builder)
    com = MetaTaskKineCom(robot)
    gotoNd(com, [50.0, 0.0, 1.0], gain=1900.0)
    sot = add_sot(robot, solver="hqp")
    sot.push(com.task.name)
    angular, linear = default_base_velocity_limit(robot.model)
    assert angular == pytest.approx(3.87) and linear == pytest.approx(3.87 * 1.0228, rel=1e-3)
    sot.setBaseVelocityLimit(1.0, 0.5)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(0.005)
    v = sot.GetOutputPort("control").Eval(sot.GetMyContextFromRoot(simulator.get_context()))
    assert np.abs(v[:3]).max() <= 1.0 + 1e-6 and np.abs(v[3:6]).max() <= 0.5 + 1e-6
    assert np.abs(v[3:6]).max() > 0.4  # it does use what it is given


def test_far_reach_keeps_the_feet_to_a_micrometre():
    """The tutorial with a target 3 m ahead and the basic SOT: the hand asks 100 times the joints'
    limits; the feet stay within 1 µm over 0.3 s (33 µm without the curvature correction, 12.6 cm
    without the scaling)."""
    from sotdrake.scenarios import talos_appli

    appli = talos_appli
    handles = appli.build_diagram(target=(3.5, -0.2, 1.0), push_time=0.05)
    simulator, wall = appli.simulate(handles, 0.3, progress=False)
    summary, _ = appli.summarize(handles, simulator, 0.3, wall)
    assert summary["min_velocity_scale"] < 0.5 and summary["scaled_ticks"] > 100
    assert summary["max_foot_drift_m"] < 1e-6


# --- items 2 and 6: gains and targets within their ranges -------------------------------------
def test_gains_that_make_the_loop_unstable_are_refused(caplog):
    from sotdrake.gains import GainAdaptive

    gain = GainAdaptive("g", dt=1e-3)
    for refused in (2000.0, 1e5, 1e308):
        with pytest.raises(InvalidInput, match="λ"):
            gain.setConstant(refused)
    with pytest.raises(InvalidInput, match="λ"):
        gain.setByPoint(2500.0, 0.9, 0.01, 0.9)
    assert gain.settings().coefficients.c == 1.0  # unchanged
    with caplog.at_level(logging.WARNING, logger="sotdrake.gains"):
        gain.setConstant(1500.0)
    assert "overshoots" in caplog.text and gain.settings().coefficients.c == 1500.0
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="sotdrake.gains"):
        gain.setConstant(900.0)
    assert not caplog.text


def test_targets_beyond_the_physical_range_are_refused(talos_model):
    from sotdrake.features.feature6d import as_transform

    for target in ([1e300, 0, 0], [101.0, 0, 0], [0, 0, 1, 7.0, 0, 0]):
        with pytest.raises(InvalidInput, match=r"100|6.28"):
            as_transform(target, "target")
    as_transform([99.0, 0, 0, 3.0, 0, 0], "target")


# --- items 4 and 5: inputs that ended the process, a rejected command that changed state --------
def test_runner_refuses_what_ended_or_hung_the_process():
    from sotdrake.interactive import Runner
    from sotdrake.robot import add_sot, talos

    builder = DiagramBuilder()
    robot = talos(builder)
    add_sot(robot)
    runner = Runner(builder.Build(), robot.dt)
    runner.go(0.01)
    for kwargs in ({"chunk": 0.0}, {"chunk": -0.1}, {"chunk": float("nan")}):
        with pytest.raises(InvalidInput, match="chunk"):
            runner.go(0.5, **kwargs)
    with pytest.raises(InvalidInput, match="target"):
        runner.advance_to(0.0)
    assert runner.t == pytest.approx(0.01)
    assert runner.advance_to(0.02) == pytest.approx(0.02)


def test_a_urdf_with_lower_above_upper_is_refused_before_drake_parses_it():
    from sotdrake.robots.urdf_checks import check_urdf_limits

    joint = ('<robot name="r"><link name="a"/><link name="b"/><joint name="knee" type="revolute">'
             '<parent link="a"/><child link="b"/><limit lower="1" upper="-1" effort="1" velocity="1"/></joint></robot>')
    with pytest.raises(RobotDescriptionError, match=r"knee.*lower=1.0 must be ≤ upper=-1.0"):
        check_urdf_limits(joint)
    check_urdf_limits(joint.replace('lower="1" upper="-1"', 'lower="-1" upper="1"'))


def test_attime_refuses_a_context_command_before_changing_anything():
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake.meta_tasks import MetaTaskKineCom
    from sotdrake.robot import add_sot, talos
    from sotdrake.sequencer import attime

    builder = DiagramBuilder()
    robot = talos(builder)
    com = MetaTaskKineCom(robot)
    sot = add_sot(robot)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    with pytest.raises(SotError, match="without context"):
        attime(1.0, lambda: sot.push(com.task.name, context))
    assert sot.stack(context) == [] and sot.stack() == []
