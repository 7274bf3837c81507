"""The benchmark harness builds its stacks and measures (no timing is asserted: numbers live in
bench/, not in tests)."""

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import run as bench  # noqa: E402


def test_stacks_and_timing():
    robot, sot, hand, diagram = bench.build_stack("cascade", tasks=10)
    assert len(sot.stack()) == 10 and sot.stack()[:3] == ["taskcontactRF", "taskcontactLF", "taskcom"]
    times, simulator, cpu = bench.time_ticks(diagram, 20, 5)
    assert cpu.shape == (20,) and np.all(cpu >= 0)
    assert times.shape == (20,) and np.all(times > 0)
    assert simulator.get_context().get_time() > 0.024  # 25 ticks of 1 ms
    summary = bench.stats(times)
    assert summary["n"] == 20 and summary["median"] <= summary["p95"] <= summary["p99"] <= summary["max"]
    _, sot_arm, _, _ = bench.build_stack("cascade", variant="left_arm", tasks=1)
    assert sot_arm.stack() == ["tasklh"]


def test_breakdown_accounts_for_the_whole_tick():
    parts = bench.breakdown(20)
    assert {"kinematics", "features/tasks", "solver", "device", "framework overhead"} <= set(parts)
    assert abs(sum(parts.values()) - 1.0) < 1e-9 and all(v >= -1e-3 for v in parts.values())


def test_reference_run_renders_and_its_targets_are_recomputed():
    """The committed reference run regenerates the README's tables, with the verdicts it stores."""
    reference = json.loads(bench.REFERENCE.read_text())
    assert bench.check_targets(reference) == reference["targets"]
    table = bench.markdown(reference)
    assert f"{reference['tick_us']['median']:.0f}" in table and "marginal cost" in table
    assert table.count("\n| ") >= 10  # the peers' rows and the targets' rows
