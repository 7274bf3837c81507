"""Trace files hold what the run did and nothing else: a file of another kind is neither read as a
trace nor overwritten, a corrupted one is an ``InvalidInput`` (or reads up to where it was cut), the
file holds the whole run once ``simulate`` returns, a file removed during the run is an error at the
next flush, and a context run again from an earlier time traces the new run. Also what a sample
is (the state before the tick at its time) and when a timed command applies (at the tick of its time)."""

from __future__ import annotations

import ast
import logging
import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Sine

from sotdrake.exceptions import InvalidInput, SotError
from sotdrake.simulation import simulate
from sotdrake.trace_chunks import ChunkFile
from sotdrake.tracing import Tracer, flush_tracers, read_trace


def _traced(stream, chunk: float = 1.0, period: float = 0.01):
    builder = DiagramBuilder()
    tracer = Tracer(builder, period, stream=stream, chunk=chunk)
    wave = builder.AddSystem(Sine(np.array([1.0, 2.0]), np.array([3.0, 1.0]), np.array([0.1, 0.2])))
    tracer.add(wave.get_output_port(0), "sine")
    return builder.Build(), tracer


def _run(diagram, simulator: Simulator, until: float, step: float = 0.01) -> None:
    for t in np.arange(simulator.get_context().get_time() + step, until + 1e-9, step):
        simulator.AdvanceTo(t)
        flush_tracers(diagram, simulator.get_context())


def _small_trace(path) -> dict[str, np.ndarray]:
    """Three chunks of ``time`` and a 2-wide ``x`` written to ``path``; returns the whole arrays."""
    file = ChunkFile(path)
    times, values = np.arange(9.0) * 0.5, np.arange(18.0).reshape(9, 2) + 0.25
    for rows in (slice(0, 3), slice(3, 5), slice(5, 9)):
        file.append({"time": times[rows], "x": values[rows]})
    return {"time": times, "x": values}


def _header_bytes(raw: bytes) -> list[int]:
    """The positions of every byte of every ``.npy`` header in ``raw`` (magic, length, dictionary)."""
    positions, at = [], 0
    while at < len(raw):
        length = int.from_bytes(raw[at + 8:at + 10], "little")
        header = ast.literal_eval(raw[at + 10:at + 10 + length].decode("latin1"))
        positions.extend(range(at, at + 10 + length))
        at += 10 + length + math.prod(header["shape"]) * np.dtype(header["descr"]).itemsize
    return positions


def _assert_a_prefix(got: dict[str, np.ndarray], whole: dict[str, np.ndarray]) -> None:
    """``got`` holds the first chunks of ``whole`` (3, 2 and 4 rows), whole, as written."""
    assert set(got) == set(whole)
    rows = got["time"].shape[0]
    assert rows in (0, 3, 5, 9), rows
    np.testing.assert_array_equal(got["time"], whole["time"][:rows])
    if rows:
        np.testing.assert_array_equal(got["x"], whole["x"][:rows])
    else:
        assert got["x"].size == 0


def test_a_file_of_another_kind_is_neither_read_as_a_trace_nor_overwritten(tmp_path):
    kinds = {"floats.npy": np.arange(1000.0), "names.npy": np.array(["a", "b"]), "table.npy": np.ones((3, 2))}
    for name, array in kinds.items():
        np.save(tmp_path / name, array)
        before = (tmp_path / name).read_bytes()
        with pytest.raises(InvalidInput, match=rf"tracer stream: .*{name}.* not a trace file"):
            Tracer(DiagramBuilder(), 1e-3, stream=tmp_path / name)
        assert (tmp_path / name).read_bytes() == before
        if name == "names.npy":  # (a list of names alone reads as a trace stopped before its first chunk)
            assert all(values.size == 0 for values in read_trace(tmp_path / name).values())
            continue
        with pytest.raises(InvalidInput, match=rf"{name}.*not a trace file"):
            read_trace(tmp_path / name)
    whole = _small_trace(tmp_path / "t.npys")
    _assert_a_prefix(read_trace(tmp_path / "t.npys"), whole)
    Tracer(DiagramBuilder(), 1e-3, stream=tmp_path / "t.npys")  # a trace file: a new run starts it over
    assert (tmp_path / "t.npys").stat().st_size == 0


def test_simulate_leaves_the_whole_run_in_the_file(tmp_path):
    diagram, tracer = _traced(tmp_path / "t.npys", chunk=1.0)
    simulator, _ = simulate(diagram, 0.25, progress=False)
    data = tracer.data(simulator.get_context())
    on_file = read_trace(tmp_path / "t.npys")
    assert data["time"].size == on_file["time"].size == 26
    for name in data:
        np.testing.assert_array_equal(on_file[name], data[name])


def test_a_corrupted_header_is_invalid_input_or_reads_the_chunks_before_it(tmp_path, caplog):
    """Every byte of every header of a small trace file, changed to a parenthesis, a digit or a
    non-ASCII byte (numpy's parser raises many kinds of errors, a digit makes a shape that does not
    fit): read_trace raises ``InvalidInput`` or returns whole chunks from the start, as they were
    written; so does a cut anywhere."""
    caplog.set_level(logging.ERROR, logger="sotdrake.tracing")
    whole = _small_trace(tmp_path / "t.npys")
    raw = (tmp_path / "t.npys").read_bytes()
    bad = tmp_path / "bad.npys"
    outcomes = {"refused": 0, "read": 0}
    for position in _header_bytes(raw):
        for value in (b"(", b"9", b"\xff"):
            bad.write_bytes(raw[:position] + value + raw[position + 1:])
            try:
                got = read_trace(bad)
            except InvalidInput:
                outcomes["refused"] += 1
                continue
            _assert_a_prefix(got, whole)
            outcomes["read"] += 1
    names_end = raw.index(b"\x93NUMPY", 1)
    for cut in range(1, len(raw), 3):
        bad.write_bytes(raw[:cut])
        try:
            got = read_trace(bad)
        except InvalidInput as error:
            assert cut <= names_end and "not a trace file" in str(error)  # (cut inside the names)
            continue
        _assert_a_prefix(got, whole)
    assert outcomes["refused"] > 100 and outcomes["read"] > 0, outcomes


def test_a_huge_shape_in_a_header_is_read_as_a_cut_chunk_not_allocated(tmp_path):
    _small_trace(tmp_path / "t.npys")
    raw = (tmp_path / "t.npys").read_bytes()
    huge = b"(" + b"9" * 18 + b",), }"  # (in the header's padding: the arrays after it stay in place)
    small = b"(3,), }" + b" " * (len(huge) - 7)
    assert raw.count(small) == 1  # (the first chunk's time)
    (tmp_path / "t.npys").write_bytes(raw.replace(small, huge))
    assert read_trace(tmp_path / "t.npys")["time"].size == 0  # (that chunk cannot be in the file: cut short)


@pytest.mark.parametrize("how", ["deleted", "replaced", "truncated"])
def test_a_stream_file_removed_during_the_run_is_an_error_at_the_next_flush(tmp_path, how):
    path = tmp_path / "t.npys"
    diagram, tracer = _traced(path, chunk=0.05)
    simulator = Simulator(diagram)
    _run(diagram, simulator, 0.2)
    if how == "deleted":
        path.unlink()
    elif how == "replaced":
        path.unlink()
        path.write_bytes(b"someone else's file")
    else:
        with open(path, "r+b") as file:
            file.truncate(100)
    after = path.read_bytes() if path.exists() else None
    with pytest.raises(SotError, match=r"trace file .*t\.npys.* (was deleted|was replaced|holds \d+ bytes, not the)"):
        _run(diagram, simulator, 0.3)
    with pytest.raises(SotError, match=r"t\.npys"):
        tracer.data(simulator.get_context())
    assert (path.read_bytes() if path.exists() else None) == after  # (nothing written there since)


@pytest.mark.parametrize("stream", [True, False, "file"])
def test_a_context_run_again_from_an_earlier_time_traces_the_new_run(tmp_path, stream):
    """Not flushed before the reset (the logs hold samples of both runs) or flushed: either way the
    trace is the second run's, its time increasing."""
    for flushed in (False, True):
        diagram, tracer = _traced(tmp_path / f"t{flushed}.npys" if stream == "file" else stream, chunk=0.25)
        simulator = Simulator(diagram)
        _run(diagram, simulator, 0.5)
        if flushed:
            flush_tracers(diagram, simulator.get_context(), force=True)
        simulator.get_mutable_context().SetTime(0.0)
        simulator.Initialize()
        _run(diagram, simulator, 0.8)
        data = tracer.data(simulator.get_context())
        np.testing.assert_allclose(data["time"], np.arange(81) * 0.01, atol=1e-12)
        if stream == "file":
            flush_tracers(diagram, simulator.get_context(), force=True)
            np.testing.assert_array_equal(read_trace(tmp_path / f"t{flushed}.npys")["time"], data["time"])


def _robot_run(dt: float, until: float, command_at: float | None = None):
    """A UR5 reaching (a second target given at ``command_at`` by ``attime``), traced every tick."""
    from sotdrake import MetaTaskKine6d, add_sot, attime, gotoNd
    from sotdrake import robot as make_robot

    builder = DiagramBuilder()
    robot = make_robot(builder, "ur5", dt=dt)
    frame = list(robot.OperationalPointsMap)[-1]
    task = MetaTaskKine6d("ee", robot, "ee", robot.OperationalPointsMap[frame])
    gotoNd(task, (0.4, 0.1, 0.5), "111", 5.0)
    sot = add_sot(robot)
    sot.push(task.task.name)
    if command_at is not None:
        attime(command_at, lambda: gotoNd(task, (0.2, 0.3, 0.3), "111", 5.0))
    tracer = Tracer(builder, dt, stream=False)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    tracer.add(sot.GetOutputPort("control"), "v")
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(until)
    return tracer.data(simulator.get_context())


def test_a_sample_is_the_state_before_the_tick_at_its_time():
    """Row k: the configuration after the ticks before k·dt, and the command that tick integrates."""
    dt = 1e-3
    data = _robot_run(dt, 0.01)
    q, v = data["q"], data["v"]
    assert np.abs(v[0]).max() > 0
    for k in range(9):  # (row 1: q0 + v(0)·dt, the tick at 0 only)
        np.testing.assert_allclose(q[k + 1], q[k] + v[k] * dt, rtol=0, atol=1e-15)


def test_a_command_at_a_tick_time_applies_at_that_tick():
    """dt = 0.9 ms and a command at 9.9 ms (tick 11): Drake computes that tick's time as 11 × 0.0009 =
    0.009899999999999999, an ulp before 0.0099; the command is due at that tick all the same."""
    dt, tick = 0.0009, 11
    reference, commanded = _robot_run(dt, 0.02), _robot_run(dt, 0.02, command_at=0.0099)
    changed = np.flatnonzero(np.abs(commanded["q"] - reference["q"]).max(axis=1))
    assert changed[0] == tick + 1  # (row k + 1: the first configuration the tick at k·dt moved)
