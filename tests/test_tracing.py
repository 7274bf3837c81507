"""The tracer's streaming mode: the same arrays as in memory, a file that reads back, clear errors."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Sine

from sotdrake.exceptions import SotError
from sotdrake.simulation import frozen_gc, simulate
from sotdrake.tracing import Tracer, flush_tracers, read_trace


def traced(stream, chunk: float = 0.1):
    builder = DiagramBuilder()
    wave = builder.AddSystem(Sine(np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 3.0]), np.zeros(3)))
    tracer = Tracer(builder, 0.001, stream=stream, chunk=chunk)
    tracer.add(wave.get_output_port(0), "wave")
    tracer.add(wave.get_output_port(1), "rate")
    return builder.Build(), tracer


def test_streamed_equals_memory_and_memory_is_bounded(tmp_path):
    memory_diagram, memory = traced(False)
    streamed_diagram, streamed = traced(tmp_path / "trace.npys")
    memory_sim, _ = simulate(memory_diagram, 1.234, progress=False)
    streamed_sim, _ = simulate(streamed_diagram, 1.234, progress=False)
    expected, got = memory.data(memory_sim.get_context()), streamed.data(streamed_sim.get_context())
    assert set(got) == {"time", "wave", "rate"} and got["wave"].shape == expected["wave"].shape == (1235, 3)
    for name in expected:
        np.testing.assert_array_equal(got[name], expected[name])
    # what stays in Drake's log after the run is less than a chunk (plus one flush interval)
    left = streamed.sinks["wave"].FindLog(streamed_sim.get_context()).num_samples()
    assert left < 0.1 / 0.001 + 0.05 / 0.001 + 1
    assert memory.sinks["wave"].FindLog(memory_sim.get_context()).num_samples() == 1235
    # simulate() wrote the end of the run when it returned: nothing is left for a forced flush
    assert left == 0 and not streamed.flush(streamed_sim.get_context(), force=True)
    back = read_trace(tmp_path / "trace.npys")
    for name in expected:
        np.testing.assert_array_equal(back[name], expected[name])
    assert streamed.path == tmp_path / "trace.npys" and memory.path is None


def test_own_simulator_flush_and_rerun_starts_over():
    diagram, tracer = traced(True, chunk=0.05)
    assert tracer.path is not None and tracer.path.exists()
    simulator = Simulator(diagram)
    for t in np.arange(1, 11) * 0.03:
        simulator.AdvanceTo(t)
        flush_tracers(diagram, simulator.get_context())
    data = tracer.data(simulator.get_context())
    np.testing.assert_allclose(data["time"], np.arange(301) * 0.001, atol=1e-12)
    np.testing.assert_allclose(data["wave"][:, 1], 2.0 * np.sin(2.0 * data["time"]), atol=1e-12)
    # a second run in a fresh context does not see the first one's chunks
    again = Simulator(diagram)
    again.AdvanceTo(0.02)
    assert tracer.data(again.get_context())["time"].shape == (21,)
    flush_tracers(diagram, again.get_context(), force=True)
    assert read_trace(tracer.path)["time"].shape == (21,)


def test_bad_arguments_are_named():
    builder = DiagramBuilder()
    with pytest.raises(SotError, match="stream"):
        Tracer(builder, 0.01, stream=3)  # type: ignore[arg-type]
    with pytest.raises(SotError, match="chunk"):
        Tracer(builder, 0.01, chunk=0.0)
    with pytest.raises(SotError, match="period"):
        Tracer(builder, 0.0)


def test_frozen_gc_unfreezes():
    import gc

    with frozen_gc():
        assert gc.get_freeze_count() > 0
    assert gc.get_freeze_count() == 0


def test_live_runner_streams_too():
    from sotdrake.live.runner import LiveRun

    diagram, tracer = traced(True, chunk=0.05)
    live = LiveRun(diagram, 0.001, realtime_rate=1000.0)
    live.run(0.3)
    context = live.simulator.get_context()
    assert tracer.sinks["wave"].FindLog(context).num_samples() <= 150  # a chunk and a flush interval at most
    data = tracer.data(context)
    np.testing.assert_allclose(data["time"], np.arange(301) * 0.001, atol=1e-9)
    np.testing.assert_allclose(data["wave"][:, 2], 3.0 * np.sin(3.0 * data["time"]), atol=1e-12)


def test_the_interactive_runner_streams_and_takes_any_tick():
    """``Runner.go``/``step``/``advance_to`` flush the streaming tracers (Drake's logs hold less
    than a chunk), and the trace is the whole run; a tick longer than ``go``'s default chunk runs."""
    from sotdrake.interactive import Runner

    builder = DiagramBuilder()
    tracer = Tracer(builder, 0.001, chunk=0.5)
    tracer.add(builder.AddSystem(Sine(np.ones(3), np.ones(3), np.zeros(3))).get_output_port(0), "s")
    diagram = builder.Build()
    runner = Runner(diagram, 0.001)
    runner.go(3.0)
    runner.step(10)
    runner.advance_to(3.2)
    assert tracer.sinks["s"].FindLog(runner.context).num_samples() <= 501
    times = tracer.data(runner.context)["time"]
    np.testing.assert_allclose(times, np.arange(3201) * 0.001, atol=1e-9)
    np.testing.assert_allclose(tracer.data(runner.context)["s"][:, 0], np.sin(times), atol=1e-12)
    assert Runner(diagram, 0.5).go(1.0) == pytest.approx(1.0)

