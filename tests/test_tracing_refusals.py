"""The tracer, the recording and the control graph refuse what they cannot do before doing anything:
a port that cannot be logged leaves the builder as it was, a path that cannot be written is named
(nothing written, the recording still going), and each root context keeps its own stream, so a
replayed clone does not wipe the original run's trace."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Integrator, PassThrough, Sine

from sotdrake.exceptions import InvalidInput
from sotdrake.simulation import simulate
from sotdrake.tracing import Tracer, flush_tracers, read_trace


def _sine(builder: DiagramBuilder) -> Sine:
    return builder.AddSystem(Sine(np.array([1.0]), np.array([3.0]), np.array([0.1])))


def _traced(stream, chunk: float = 0.1):
    builder = DiagramBuilder()
    tracer = Tracer(builder, 0.01, stream=stream, chunk=chunk)
    tracer.add(_sine(builder).get_output_port(0), "sine")
    return builder.Build(), tracer


def _bad_paths(tmp_path):
    import os

    (tmp_path / "file.txt").write_text("mine")
    if not (tmp_path / "fifo").exists():
        os.mkfifo(tmp_path / "fifo")  # (writing to it would wait for a reader)
    return [tmp_path / "missing" / "out.x", tmp_path / "file.txt" / "out.x", str(tmp_path / "a\0b.x"), tmp_path / "fifo"]


def test_add_refuses_a_port_it_cannot_log_and_leaves_the_builder_as_it_was():
    builder, other = DiagramBuilder(), DiagramBuilder()
    source = builder.AddSystem(ConstantVectorSource(np.ones(2)))
    pose = builder.AddSystem(PassThrough(AbstractValue.Make(RigidTransform())))
    builder.Connect(builder.AddSystem(PassThrough(AbstractValue.Make(RigidTransform()))).get_output_port(),
                    pose.get_input_port())
    foreign = _sine(other)
    tracer = Tracer(builder, 0.01, stream=False)
    tracer.add(source.get_output_port(), "ok")
    systems = [system.get_name() for system in builder.GetSystems()]
    for port, reason in ((pose.get_output_port(), "abstract"), (foreign.get_output_port(0), "another builder"),
                         (None, "NoneType"), ("ok", "str")):
        with pytest.raises(InvalidInput, match=f"'signal'.*vector output port of a system of this builder.*{reason}"):
            tracer.add(port, "signal")  # type: ignore[arg-type]
        assert [system.get_name() for system in builder.GetSystems()] == systems and list(tracer.sinks) == ["ok"]
    with pytest.raises(InvalidInput, match="DiagramBuilder"):
        Tracer(None, 0.01)  # type: ignore[arg-type]
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(0.03)
    assert tracer.data(simulator.get_context())["ok"].shape == (4, 2)


def test_a_replayed_clone_keeps_the_original_trace():
    def run(stream):
        diagram, tracer = _traced(stream)
        simulator = Simulator(diagram)
        context = simulator.get_context()
        for k in range(1, 11):
            simulator.AdvanceTo(0.05 * k)
            flush_tracers(diagram, context)
        clone = context.Clone()
        for k in range(11, 21):
            simulator.AdvanceTo(0.05 * k)
            flush_tracers(diagram, context)
        replay = Simulator(diagram, clone)
        for k in range(11, 21):
            replay.AdvanceTo(0.05 * k)
            flush_tracers(diagram, clone)
        return tracer.data(context), tracer.data(clone)

    (original, clone), (kept_original, kept_clone) = run(True), run(False)
    assert original["time"][0] == clone["time"][0] == 0.0 and original["time"].size == 101
    for got, expected in ((original, kept_original), (clone, kept_clone)):
        for name in expected:
            np.testing.assert_array_equal(got[name], expected[name])


def test_a_clone_taken_right_after_a_flush_starts_with_the_original_chunks():
    diagram, tracer = _traced(True, chunk=0.05)
    simulator = Simulator(diagram)
    context = simulator.get_context()
    for k in range(1, 5):
        simulator.AdvanceTo(0.05 * k)
        flush_tracers(diagram, context, force=True)
    assert tracer.sinks["sine"].FindLog(context).num_samples() == 0
    clone = context.Clone()
    np.testing.assert_array_equal(tracer.data(clone)["time"], tracer.data(context)["time"])
    replay = Simulator(diagram, clone)
    replay.AdvanceTo(0.3)
    flush_tracers(diagram, clone, force=True)
    assert tracer.data(clone)["time"][0] == 0.0 and tracer.data(clone)["time"][-1] == pytest.approx(0.3)
    assert tracer.data(context)["time"].size == 21


def test_a_new_context_set_to_a_later_time_is_not_taken_for_a_clone():
    """A new context (not a clone) started at t = 0.5 s, where another run's chunk ends: its trace
    is its own run, as with ``stream=False`` (an integrator: its state there is not the other run's)."""
    def run(stream):
        builder = DiagramBuilder()
        tracer = Tracer(builder, 0.01, stream=stream, chunk=0.5)
        source, integrator = builder.AddSystem(ConstantVectorSource(np.ones(1))), builder.AddSystem(Integrator(1))
        builder.Connect(source.get_output_port(), integrator.get_input_port())
        tracer.add(integrator.get_output_port(0), "x")
        diagram = builder.Build()
        first = Simulator(diagram)
        for k in range(1, 21):
            first.AdvanceTo(0.1 * k)
            flush_tracers(diagram, first.get_context())
        context = diagram.CreateDefaultContext()
        context.SetTime(0.5)
        second = Simulator(diagram, context)
        for k in range(6, 21):
            second.AdvanceTo(0.1 * k)
            flush_tracers(diagram, context)
        return tracer.data(context)

    streamed, kept = run(True), run(False)
    assert streamed["time"][0] == 0.5 and streamed["time"].size == 151
    for name in kept:
        np.testing.assert_array_equal(streamed[name], kept[name])


@pytest.mark.parametrize("stream", [True, False])
def test_a_tracer_without_signals_saves_an_empty_time_and_refuses_to_plot(tmp_path, stream):
    builder = DiagramBuilder()
    _sine(builder)
    tracer = Tracer(builder, 0.01, stream=stream)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(0.1)
    context = simulator.get_context()
    assert {name: value.shape for name, value in tracer.data(context).items()} == {"time": (0,)}
    assert tracer.save_csv(context, tmp_path / "t.csv").read_text().strip() == "time"
    assert set(np.load(tracer.save(context, tmp_path / "t.npz"))) == {"time"}
    with pytest.raises(InvalidInput, match="no signal is traced"):
        tracer.plot(context, tmp_path / "t.png")
    assert not (tmp_path / "t.png").exists()


def test_a_second_run_takes_the_file_and_the_first_keeps_its_trace(tmp_path):
    diagram, tracer = _traced(tmp_path / "trace.npys")
    first, _ = simulate(diagram, 0.5, progress=False)
    second, _ = simulate(diagram, 0.3, progress=False)
    flush_tracers(diagram, second.get_context(), force=True)
    assert read_trace(tmp_path / "trace.npys")["time"].size == 31
    assert tracer.data(first.get_context())["time"].size == 51
    assert tracer.data(second.get_context())["time"].size == 31


def test_runs_after_runs_through_one_diagram_keep_no_files_open(tmp_path, monkeypatch):
    """A sweep's cases, each a new Simulator of one diagram: a run's stream goes with its context,
    so the temporary files (and the file descriptors) do not pile up with the runs."""
    import gc
    import os
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # (this test's temporary files only)
    diagram, tracer = _traced(True)
    counts = []
    for _ in range(30):
        simulator, _ = simulate(diagram, 0.3, progress=False)
        assert tracer.data(simulator.get_context())["time"].size == 31
        del simulator
        gc.collect()
        counts.append((len(os.listdir(tmp_path)), len(os.listdir("/proc/self/fd"))))
    assert counts[-1] == counts[4], counts


def test_tracer_files_to_a_path_that_cannot_be_written_are_refused(tmp_path):
    diagram, tracer = _traced(False)
    simulator, _ = simulate(diagram, 0.05, progress=False)
    context = simulator.get_context()
    paths = _bad_paths(tmp_path)
    before = sorted(tmp_path.rglob("*"))
    for path in paths:
        for save in (tracer.save, tracer.save_csv, tracer.plot):
            with pytest.raises(InvalidInput, match=r"tracer: \w+: cannot write .*(out\.x|fifo)|a\\x00b"):
                save(context, path)
    assert sorted(tmp_path.rglob("*")) == before
    assert tracer.save(context, tmp_path / "t.npz").is_file()


def test_save_recording_checks_the_path_before_stopping_the_recording(tmp_path):
    from pydrake.geometry import Meshcat, MeshcatVisualizer

    from sotdrake.visualization import save_recording

    calls: list[str] = []

    class Watched(MeshcatVisualizer):
        def StopRecording(self):
            calls.append("stop")
            super().StopRecording()

        def PublishRecording(self):
            calls.append("publish")
            super().PublishRecording()

    meshcat = Meshcat()
    visualizer = Watched(meshcat)
    visualizer.StartRecording(False)
    for path in _bad_paths(tmp_path):
        with pytest.raises(InvalidInput, match="save_recording"):
            save_recording(visualizer, meshcat, path)
    assert calls == []
    assert save_recording(visualizer, meshcat, tmp_path / "recording.html").read_text().strip()
    assert calls == ["stop", "publish"]


def test_write_control_graph_refuses_a_path_it_cannot_write(tmp_path):
    from sotdrake.visualization import write_control_graph

    builder = DiagramBuilder()
    _sine(builder)
    diagram = builder.Build()
    for path in _bad_paths(tmp_path):
        with pytest.raises(InvalidInput, match="write_control_graph: cannot write"):
            write_control_graph(diagram, path)
    with pytest.raises(InvalidInput, match="diagram"):
        write_control_graph(None, tmp_path / "g.svg")  # type: ignore[arg-type]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fifo", "file.txt"]
    assert write_control_graph(diagram, tmp_path / "g.svg").exists() and (tmp_path / "g.dot").exists()


def test_a_streaming_tracer_leaves_no_open_file_and_no_file_at_exit(tmp_path):
    """The temporary chunk file is a path, not an open file: no ResourceWarning when the process
    ends with a tracer alive, and the file is gone after it."""
    import subprocess
    import sys

    code = ("import numpy as np, tempfile\n"
            f"tempfile.tempdir = {str(tmp_path)!r}\n"
            "from sotdrake.trace_chunks import ChunkFile\n"
            "kept = ChunkFile(None)\n"
            "kept.append({'time': np.arange(3.0), 'x': np.ones((3, 2))})\n"
            "copy = kept.prefix(1)\n"
            "print(len(list(__import__('pathlib').Path(tempfile.tempdir).iterdir())))\n")
    result = subprocess.run([sys.executable, "-X", "dev", "-W", "error::ResourceWarning", "-c", code],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and "ResourceWarning" not in result.stderr, result.stderr
    assert result.stdout.strip() == "2" and list(tmp_path.iterdir()) == []
