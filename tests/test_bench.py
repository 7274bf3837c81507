"""The benchmark harness builds its stacks and measures (no timing is asserted: numbers live in
bench/, not in tests)."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import run as bench


def test_stacks_and_timing():
    robot, sot, hand, diagram = bench.build_stack("cascade", tasks=10)
    assert len(sot.stack()) == 10 and sot.stack()[:3] == ["taskcontactRF", "taskcontactLF", "taskcom"]
    times, simulator, cpu = bench.time_ticks(diagram, 20, 5)
    assert times.shape == (20,) and cpu.shape == (20,)
    # 5 + 20 calls, each advancing over exactly one device tick (at 0, 1 ms, …, 24 ms)
    assert simulator.get_context().get_time() == pytest.approx(24.5e-3, abs=1e-12)
    assert simulator.get_num_discrete_updates() == 25
    summary = bench.stats(times)
    assert summary["n"] == 20 and summary["median"] <= summary["p95"] <= summary["p99"] <= summary["max"]
    _, sot_arm, _, _ = bench.build_stack("cascade", variant="left_arm", tasks=1)
    assert sot_arm.stack() == ["tasklh"]


def test_interleaved_runs_advance_in_turns_and_all_end():
    """bench/run.py's long runs share the host's seconds: each run advances its share of ticks in
    turn (here 3 and 1 a turn), none is dropped or run twice, and each one's result comes back."""
    log = []

    def ticks(name, count):
        for _ in range(count):
            log.append(name)
            yield
        return f"{name}: {count} ticks"

    results = bench.interleave({"a": (ticks("a", 12), 12), "b": (ticks("b", 4), 4)}, turns=4)
    assert results == {"a": "a: 12 ticks", "b": "b: 4 ticks"}
    assert "".join(log) == "aaab" * 4


def test_breakdown_accounts_for_the_whole_tick():
    calls: dict = {}
    parts = bench.breakdown(20, calls)
    assert {"kinematics", "features/tasks", "solver", "device", "framework overhead"} <= set(parts)
    # every timed function was really intercepted, once per evaluation: the device updates and the
    # solver computes once per tick; each of the 4 tasks' feature, task and desired value once too;
    # the kinematics' plant context is set once per tick (a cache entry)
    assert calls["device.Device._update"] == 20 and calls["sot.SOT._calc"] == 20
    assert calls["kinematics.Dynamic._calc_plant_context"] == 20
    assert calls["base.Feature._calc"] == 4 * 20 and calls["task._TaskBase._calc"] == 4 * 20


def test_reference_run_renders_and_its_targets_are_recomputed():
    """The committed reference run regenerates the README's tables, with the verdicts it stores."""
    reference = json.loads(bench.REFERENCE.read_text())
    assert bench.check_targets(reference) == reference["targets"]
    table = bench.markdown(reference)
    assert f"{reference['tick_us']['median']:.0f}" in table and "marginal cost" in table
    assert table.count("\n| ") >= 10  # the peers' rows and the targets' rows


def test_dynamics_bench_runs_both_peers_briefly():
    """bench/dynamics.py's runners on a few ticks (placo's only where it is installed: the bench
    extra), so the bench does not rot between reference runs."""
    import dynamics as dynamics_bench

    row = dynamics_bench.run_sotdrake("lift_leg", 0.02)
    assert {"tick_cpu_us_median", "floor_tick_cpu_us_median", "com_rms_error_m", "max_torque_ratio"} <= set(row)
    assert not row["fell"] and row["ratio_to_floor_cpu_median"] > 0
    pytest.importorskip("placo")
    assert dynamics_bench.run_placo("lift_leg", 0.02)["com_rms_error_m"] < 1e-3


def test_framework_floor_runs_every_callback_at_every_tick():
    """bench/floor.py's graph recomputes each of its per-task callbacks once per tick (the device's
    update invalidates them), as the real stack does: otherwise its floor would be too low."""
    import floor

    calls: dict = {}
    originals = {cls: cls._calc for cls in (floor._Kinematics, floor._Feature, floor._Gain, floor._Task, floor._Solver)}

    def counted(cls):
        def calc(self, context, output):
            calls[cls.__name__] = calls.get(cls.__name__, 0) + 1
            originals[cls](self, context, output)
        return calc

    try:
        for cls in originals:
            cls._calc = counted(cls)
        simulator = bench.Simulator(floor.build(3))
        simulator.Initialize()
        calls.clear()
        simulator.AdvanceTo(10.5e-3)  # the ticks at 0, 1, …, 10 ms
    finally:
        for cls, calc in originals.items():
            cls._calc = calc
    ticks = 11
    assert calls == {"_Kinematics": 2 * 3 * ticks, "_Feature": 3 * ticks, "_Gain": 3 * ticks, "_Task": 3 * ticks, "_Solver": ticks}
    wall, cpu = bench.interleaved_medians({1: floor.build(1), 2: floor.build(2)}, 100, 10)  # as run.py's scaling
    assert set(cpu) == {1, 2} and np.isfinite(list(cpu.values())).all()


def test_twin_keeps_the_graph_and_recomputes_every_connected_output_at_every_tick():
    """bench/twin.py's floor of the dynamic stack: the same systems, ports, wiring and feedthrough as
    the real diagram; every connected output of a twin is recomputed at least once per tick (the
    device's update invalidates them, as in the real diagram), and the twin's state does not move."""
    from pydrake.systems.analysis import Simulator
    from twin import twin

    from sotdrake.scenarios import talos_dynamics as td

    run = td.build_diagram("lift_leg", "dynsimu")
    real = Simulator(run.diagram)
    real.Initialize()
    floor = twin(run.diagram, real.get_context())
    by_name = {s.get_name(): s for s in floor.GetSystems()}
    assert sorted(by_name) == sorted(s.get_name() for s in run.diagram.GetSystems())
    wiring = {(s.get_name(), int(i)): (o_s.get_name(), int(o)) for (s, i), (o_s, o) in run.diagram.connection_map().items()}
    assert wiring == {(s.get_name(), int(i)): (o_s.get_name(), int(o)) for (s, i), (o_s, o) in floor.connection_map().items()}
    for system in run.diagram.GetSystems():
        other = by_name[system.get_name()]
        assert [other.get_output_port(o).get_name() for o in range(other.num_output_ports())] == \
            [system.get_output_port(o).get_name() for o in range(system.num_output_ports())]
        for (s, i) in wiring:
            if s == system.get_name():
                for o in range(system.num_output_ports()):
                    assert other.HasDirectFeedthrough(i, o) == system.HasDirectFeedthrough(i, o)
    calls: dict = {}
    counted = twin(run.diagram, real.get_context(), calls)
    simulator = Simulator(counted)
    simulator.Initialize()
    device = counted.GetSystems()[[s.get_name() for s in counted.GetSystems()].index("device")]
    state0 = device.GetMyContextFromRoot(simulator.get_context()).get_discrete_state(0).get_value().copy()
    calls.clear()
    simulator.AdvanceTo(10.5e-3)  # the ticks at 1, …, 10 ms (the one at 0 ran in Initialize)
    python = {s.get_name() for s in run.diagram.GetSystems() if type(s).__module__.startswith("sotdrake")}
    sources = {source for source in wiring.values() if source[0] in python}
    assert sources and all(calls.get(source, 0) >= 10 for source in sources), {s: calls.get(s) for s in sources}
    after = device.GetMyContextFromRoot(simulator.get_context()).get_discrete_state(0).get_value()
    assert np.array_equal(after, state0)


@pytest.mark.parametrize("contact_solver", ["sap", "tamsi"])
def test_the_physics_bench_replays_the_torques_to_the_runs_state(contact_solver):
    """The torque-driven plant alone, fed the torques a run's controller sent it, reaches that run's
    state bit for bit: the bench's plant-alone time is the run's plant."""
    import physics

    run = physics.talos_dynamics.build_diagram("stand", "physics", contact_solver=contact_solver)
    simulator = physics.Simulator(run.diagram)
    simulator.AdvanceTo(0.05)
    _, x = physics.torque_replay(run, run.tracer.data(simulator.get_context()), "hydroelastic", contact_solver, 0.05)
    plant = run.robot.physical.plant
    np.testing.assert_array_equal(x, plant.GetPositionsAndVelocities(plant.GetMyContextFromRoot(simulator.get_context())))


def test_the_physics_bench_runs_each_model_and_keeps_the_outcome(tmp_path):
    """``bench/physics.py`` end to end on a short run: every run of every contact model gives a CPU
    time, a real-time factor that is its inverse, a plant's share, its plant step and its outcome
    figures (standing)."""
    import physics

    results = physics.main(["--duration", "0.02", "--repeat", "1", "--out", str(tmp_path / "p.json")])
    assert json.loads((tmp_path / "p.json").read_text()) == json.loads(json.dumps(results))
    assert set(results["runs"]) == set(physics.CONTACT_MODELS)
    for runs in results["runs"].values():
        assert set(runs) == set(physics.RUNS)
        for run in runs.values():
            assert run["cpu_per_sim_s"] > 0 and run["realtime_factor"] == pytest.approx(1 / run["cpu_per_sim_s"])
            assert run["plant_share"] > 0 and run["outcome"]["fell"] is False
        assert runs["reach"]["plant_step_s"] == physics.PLANT_STEP and runs["reach_plant_1ms"]["plant_step_s"] == 1e-3


def test_the_collision_bench_breaks_the_tick_down_and_restores_the_calls():
    """bench/collisions.py's breakdown: the schedule (its gaps within it), the rows and the solver are
    separate calls within the tick, each timed; the wrapped calls are put back afterwards."""
    import collisions

    from sotdrake.collision.distance import PairTable
    from sotdrake.collision.schedule import PairSchedule
    from sotdrake.solvers import solver_kine

    originals = (PairSchedule.step, PairSchedule.gaps, PairTable.distances, solver_kine.solve_stack)
    parts = collisions.breakdown(30)
    assert (PairSchedule.step, PairSchedule.gaps, PairTable.distances, solver_kine.solve_stack) == originals
    assert all(parts[name] > 0 for name in ("schedule", "rows", "solver"))
    assert parts["gaps"] <= parts["schedule"]
    assert parts["schedule"] + parts["rows"] + parts["solver"] <= parts["tick"]


def test_the_marginal_bench_adds_one_task_of_each_kind_and_summarizes_every_repeat(tmp_path):
    """bench/marginal.py: each kind's stack is the base stack and one more task of that kind at the
    bottom (its rows: 6, 3, one per joint), under both kinematic solvers; the figures are the medians over the
    repeats of each repeat's differences, and the floor's slope is fitted on 2 to 6 tasks."""
    import marginal

    for solver, key in marginal.SOLVERS.items():
        for kind, name in marginal.KINDS.items():
            robot, sot, _, diagram = bench.build_stack(key, names=[*marginal.BASE, name], full_6d=True)
            base = ["taskcontactRF", "taskcontactLF", "taskrh"]
            assert sot.stack() == [*base, f"task{name}"], solver
            rows = {"6D": 6, "CoM": 3, "posture": robot.dimension - 6}[kind]  # (the posture: every joint, not the base)
            level = sot.GetInputPort(f"task{name}").Eval(sot.GetMyContextFromRoot(diagram.CreateDefaultContext()))
            assert level.jacobian.shape == (rows, robot.dimension)
    rounds = []
    for k in range(3):  # the floor 10 + 3 µs per task (+ k), each kind costing 1, 2, 3 floor slopes (+ k)
        r = {("floor", n): 10.0 + 3.0 * n + k for n in marginal.FLOOR_TASKS}
        for i, solver in enumerate(marginal.SOLVERS):
            r[(solver, None)] = 100.0 * (i + 1)
            r.update({(solver, kind): 100.0 * (i + 1) + 3.0 * (j + 1) + k for j, kind in enumerate(marginal.KINDS)})
        rounds.append(r)
    summary = marginal.summarize(rounds)
    assert summary["floor_slope_cpu_us"] == pytest.approx(3.0)
    kinds = summary["solvers"]["SolverKine"]["kinds"]
    assert summary["solvers"]["SolverKine"]["base_tick_cpu_us"] == 200.0
    assert [kinds[kind]["marginal_cpu_us"] for kind in marginal.KINDS] == pytest.approx([4.0, 7.0, 10.0])
    assert [kinds[kind]["target_met"] for kind in marginal.KINDS] == [True, False, False]
    assert kinds["CoM"]["ratio_to_floor_slope"] == pytest.approx(7.0 / 3.0)
    result = marginal.main(["--ticks", "50", "--warmup", "5", "--repeat", "1", "--out", str(tmp_path / "m.json")])
    assert json.loads((tmp_path / "m.json").read_text())["solvers"].keys() == {"SOT", "SolverKine"}
    assert np.isfinite([k["marginal_cpu_us"] for r in result["solvers"].values() for k in r["kinds"].values()]).all()


def test_the_hierarchical_peer_answers_a_stack_and_its_comparison_is_lexicographic():
    """DAQP's hierarchical mode (bench/hierarchical_peer.py) meets a feasible top level and gets the
    level below as close as the top allows; the comparison decides at the first level that differs."""
    from hierarchical_peer import compare, daqp_hierarchical, violations

    from sotdrake.hqp.solve import HierarchicalQP, LevelRows

    top = LevelRows(np.array([[1.0, 1.0]]), np.array([1.0]), np.array([1.0]))  # x₁ + x₂ = 1
    below = LevelRows(np.array([[1.0, 1.0], [1.0, -1.0]]), np.array([3.0, 0.5]), np.array([np.inf, 0.5]))  # conflicts
    bounds = np.full(2, -10.0), np.full(2, 10.0)
    x, flag = daqp_hierarchical(2, [top, below], *bounds)
    assert flag > 0 and violations([top], x)[0] < 1e-9
    assert violations([top, below], x)[1] == pytest.approx(4.0, rel=1e-4)  # x₁ + x₂ ≥ 3 misses by 2; x₁ − x₂ = ½ met
    exact = HierarchicalQP(2).solve([top, below], *bounds).x
    assert compare([top, below], x, exact)[0] == 0
    off_top = exact + np.array([0.5, 0.5])  # the level below gains, the top loses: worse
    assert compare([top, below], off_top, exact) == (1, False)
    assert compare([top, below], exact, off_top) == (-1, False)
