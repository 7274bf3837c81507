"""Traces, bags, the live channel and its connection file: a bad input or a broken file is refused
as a :class:`SotError` (or answered, on the live channel) and leaves what exists as it was; a run
stopped halfway keeps what it recorded."""

from __future__ import annotations

import csv
import json
import os
import socket
import threading
import time
import types

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

import sotdrake.simulation as simulation
from sotdrake import InvalidInput, MetaTaskKine6d, SotError, add_sot, simulate, talos
from sotdrake.live.connection import read_connection
from sotdrake.live.framing import LineReader
from sotdrake.tracing import Tracer, read_trace


def _traced_stack(stream):
    builder = DiagramBuilder()
    robot = talos(builder)
    sot = add_sot(robot)
    waist = MetaTaskKine6d("waist", robot, "waist", "root_joint")
    sot.push(waist)
    tracer = Tracer(builder, robot.dt, stream=stream, chunk=1.0)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    return builder, robot, tracer


def test_two_tracers_of_one_signal_name_or_one_file(tmp_path):
    builder, robot, tracer = _traced_stack(tmp_path / "a.npys")
    other = Tracer(builder, robot.dt, stream=False)
    with pytest.raises(InvalidInput, match="another tracer"):
        other.add(robot.device.GetOutputPort("state"), "q")  # (Drake would abort at Build on the two names)
    with pytest.raises(InvalidInput, match="another tracer streams"):
        Tracer(builder, robot.dt, stream=tmp_path / "a.npys")
    for name in ("", 5, "a/b", "time"):
        with pytest.raises(InvalidInput):
            tracer.add(robot.device.GetOutputPort("state"), name)
    with pytest.raises(InvalidInput, match="period"):
        Tracer(builder, float("inf"))
    builder.Build()
    with pytest.raises(SotError, match="already built"):
        tracer.add(robot.device.GetOutputPort("state"), "q2")


def test_an_interrupted_run_keeps_its_samples(tmp_path, monkeypatch):
    builder, _, tracer = _traced_stack(tmp_path / "run.npys")

    class Interrupted(simulation.Simulator):  # Ctrl-C after 0.3 s, inside the first 1 s chunk
        def AdvanceTo(self, t):
            if t > 0.31:
                raise KeyboardInterrupt
            return super().AdvanceTo(t)

    monkeypatch.setattr(simulation, "Simulator", Interrupted)
    with pytest.raises(KeyboardInterrupt):
        simulate(builder.Build(), 1.0, progress=False)
    trace = read_trace(tmp_path / "run.npys")
    assert trace["time"][-1] == pytest.approx(0.3) and len(trace["time"]) == len(trace["q"]) >= 300


def test_a_chunk_cut_short_reads_up_to_it(tmp_path):
    path = tmp_path / "cut.npys"
    tracer = Tracer(DiagramBuilder(), 1e-3, stream=path)
    tracer._file.append({"time": np.arange(3.0), "x": np.ones((3, 2))})  # type: ignore[union-attr]
    tracer._file.append({"time": np.arange(3.0, 6.0), "x": np.zeros((3, 2))})  # type: ignore[union-attr]
    whole = path.read_bytes()
    path.write_bytes(whole[:-20])
    trace = read_trace(path)
    assert trace["time"].tolist() == [0.0, 1.0, 2.0] and trace["x"].shape == (3, 2)
    with pytest.raises(InvalidInput, match=r"missing\.npys"):
        read_trace(tmp_path / "missing.npys")


def test_write_bag_keeps_what_it_cannot_replace(tmp_path):
    pytest.importorskip("rosbags")
    from sotdrake.ros.bag import read_bag, write_bag

    t, joints = np.arange(5) * 0.1, (["a", "b"], np.arange(10.0).reshape(5, 2))
    bag = tmp_path / "bag"
    write_bag(bag, t, joints)
    with pytest.raises(InvalidInput, match="time"):
        write_bag(bag, t - 1.0, joints)  # (negative stamps)
    with pytest.raises(InvalidInput, match="rows"):
        write_bag(bag, t, joints, arrays={"/x": np.zeros(4)})
    assert len(read_bag(bag)["/joint_states"]) == 5  # the old bag, whole
    folder = tmp_path / "notes"
    folder.mkdir()
    (folder / "data.txt").write_text("mine")
    with pytest.raises(InvalidInput, match="not a bag"):
        write_bag(folder, t, joints)
    assert (folder / "data.txt").read_text() == "mine"


@pytest.mark.parametrize("text", ["{", "[]", "{}", '{"host": "h", "port": 70000, "token": "t", "pid": 1}'])
def test_a_broken_connection_file(tmp_path, text):
    path = tmp_path / "live.json"
    path.write_text(text)
    path.chmod(0o600)
    with pytest.raises(InvalidInput, match="connection file"):
        read_connection(path)


def test_the_token_line_has_one_deadline():
    """A client sending one byte at a time cannot hold a connection past the deadline."""
    server, client = socket.socketpair()
    try:
        reader = LineReader(server)
        reader.deadline = time.monotonic() + 0.5
        stop = threading.Event()

        def trickle():
            while not stop.wait(0.1):
                try:
                    client.send(b"x")
                except OSError:
                    return

        threading.Thread(target=trickle, daemon=True).start()
        begin = time.monotonic()
        with pytest.raises(TimeoutError):
            next(reader.lines())
        assert time.monotonic() - begin < 5.0  # (bytes every 0.1 s: without one deadline, it would wait forever)
        stop.set()
    finally:
        server.close()
        client.close()


@pytest.mark.parametrize("options", [{"dt": float("inf")}, {"dt": 0.0}, {"dt": True}, {"port": 70000},
                                     {"realtime_rate": "x"}, {"max_lag": float("nan")}, {"command_share": "x"}])
def test_live_run_options(options):
    from sotdrake.live.runner import LiveRun

    builder = DiagramBuilder()
    builder.AddSystem(ConstantVectorSource(np.zeros(1)))
    arguments = {"dt": 1e-3, **options}
    with pytest.raises(InvalidInput):
        LiveRun(builder.Build(), **arguments)


@pytest.mark.parametrize("data", ['{"command": "\\ud800"}', '{"a":' * 100000, '{"command": 5}', "{"])
def test_a_hostile_ros_request_is_answered(data):
    pytest.importorskip("rclpy")
    from std_msgs.msg import String

    from sotdrake.ros.services import RosServices

    answers: list[dict] = []
    services = types.SimpleNamespace(respond=answers.append)
    RosServices._request(services, String(data=data))  # type: ignore[arg-type]
    assert len(answers) == 1 and answers[0]["ok"] is False
    json.dumps(answers[0])


def test_sweep_inputs_are_checked_before_any_case_runs():
    from sotdrake.sweep.cases import grid, random_cases
    from sotdrake.sweep.engines import run_sweep
    from sotdrake.sweep.table import flatten

    ran: list[dict] = []
    with pytest.raises(InvalidInput, match="status"):
        run_sweep(lambda case: ran.append(case) or {}, [{"x": 1}, {"status": 2}], progress=False)
    assert ran == []
    for axes in ({"status": [1, 2]}, {"x": None}, {"x": (i for i in range(3))}, {"": [1]}):
        with pytest.raises(InvalidInput):
            grid(axes)
    for ranges, seed in (({"x": (0, 1, 2)}, 0), ({"x": (0, "a")}, 0), ({"x": (-1e308, 1e308)}, 0), ({"x": (0, 1)}, -1)):
        with pytest.raises(InvalidInput):
            random_cases(3, ranges, seed)
    with pytest.raises(InvalidInput, match="callable"):
        run_sweep("f", [{"x": 1}], progress=False)  # type: ignore[arg-type]
    with pytest.raises(InvalidInput, match="two values"):
        flatten({"a.b": 1, "a": {"b": 2}})


def test_a_case_that_stops_the_process_is_an_error_row():
    from sotdrake.sweep.engines import run_sweep

    def case(parameters):
        if parameters["x"] == 1:
            raise SystemExit("bad case")
        return {"y": parameters["x"]}

    result = run_sweep(case, [{"x": 0}, {"x": 1}, {"x": 2}], progress=False)
    assert [row["status"] for row in result.rows] == ["ok", "error", "ok"] and "bad case" in result.rows[1]["error"]


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs a full device (/dev/full)")
def test_a_live_run_whose_trace_cannot_be_written_stops_and_writes_its_files(tmp_path, monkeypatch):
    from sotdrake.live.runner import run_live

    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))  # (its connection file: not the user's)

    builder = DiagramBuilder()
    robot = talos(builder)
    sot = add_sot(robot)
    sot.push(MetaTaskKine6d("waist", robot, "waist", "root_joint"))
    tracer = Tracer(builder, robot.dt, stream="/dev/full", chunk=0.05)  # (every write fails: no space left)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    handles = types.SimpleNamespace(diagram=builder.Build(), robot=robot, sot=sot, tracer=tracer)
    with pytest.raises(SotError, match="trace could not be written"):
        run_live(handles, tmp_path, duration=0.5, realtime_rate=10.0)
    assert (tmp_path / "summary.json").is_file()


@pytest.mark.parametrize("data", ['{"id": "r7", "command": 5}', '{"id": "r7", "command": "\\ud800"}', '{"id": "r7"}'])
def test_a_refused_ros_request_is_answered_to_its_id(data):
    """A client waits for the answer to its id: a request refused before it reached the runner was
    answered with id null, and the client waited its whole timeout."""
    pytest.importorskip("rclpy")
    from std_msgs.msg import String

    from sotdrake.ros.services import RosServices

    answers: list[dict] = []
    RosServices._request(types.SimpleNamespace(respond=answers.append), String(data=data))  # type: ignore[arg-type]
    assert answers == [{"id": "r7", "ok": False, "error": answers[0]["error"]}]


def test_a_trace_file_is_the_only_file_a_tracer_overwrites(tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    for stream in (notes, tmp_path / "a\0b", tmp_path / "missing" / "t.npys", tmp_path):
        with pytest.raises(InvalidInput, match="tracer stream"):
            Tracer(DiagramBuilder(), 1e-3, stream=stream)
    assert notes.read_text() == "mine"
    trace = tmp_path / "t.npys"
    Tracer(DiagramBuilder(), 1e-3, stream=trace)._file.append({"time": np.arange(2.0)})  # type: ignore[union-attr]
    Tracer(DiagramBuilder(), 1e-3, stream=trace)  # a trace file: a new run starts it over
    assert trace.stat().st_size == 0


def test_any_signal_name_is_saved_and_read_back(tmp_path):
    """``file`` and ``allow_pickle`` were taken by numpy as its own arguments (a raw TypeError, or a
    series silently dropped from ``trace.npz``); a comma shifted the CSV's columns; a trailing NUL
    merged two names in the chunk file."""
    builder = DiagramBuilder()
    tracer = Tracer(builder, 0.01, stream=tmp_path / "t.npys", chunk=0.02)
    names = ("file", "allow_pickle", "force x,y", 'say "hi"')
    for k, name in enumerate(names):
        tracer.add(builder.AddSystem(ConstantVectorSource(np.full(2, float(k)))).get_output_port(), name)
    with pytest.raises(InvalidInput, match="control characters"):
        tracer.add(builder.AddSystem(ConstantVectorSource(np.zeros(1))).get_output_port(), "file\0")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    for t in (0.02, 0.04, 0.05):
        simulator.AdvanceTo(t)
        tracer.flush(simulator.get_context())
    data = tracer.data(simulator.get_context())
    with np.load(tracer.save(simulator.get_context(), tmp_path / "t")) as saved:  # (".npz" appended, as numpy does)
        assert sorted(saved.files) == sorted(["time", *names])
        for k, name in enumerate(names):
            assert np.array_equal(saved[name], data[name]) and (saved[name] == k).all()
    outputs = simulation.write_run(tmp_path / "run", diagram, {"n": np.int64(3), "x": np.float32(0.5), "v": np.arange(2)},
                                   data, graph=False)
    assert set(np.load(outputs["trace"]).files) == {"time", *names}
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["v"] == [0, 1]
    with open(tracer.save_csv(simulator.get_context(), tmp_path / "t.csv")) as file:
        rows = list(csv.reader(file))
    assert rows[0][5:7] == ["force x,y[0]", "force x,y[1]"] and rows[0][7] == 'say "hi"[0]'
    assert all(len(row) == len(rows[0]) for row in rows)


def test_a_file_cut_inside_its_first_chunk_reads_as_empty(tmp_path):
    path = tmp_path / "cut.npys"
    Tracer(DiagramBuilder(), 1e-3, stream=path)._file.append({"time": np.arange(3.0), "x": np.ones((3, 2))})  # type: ignore[union-attr]
    whole = path.read_bytes()
    for cut in range(len(whole) // 2, len(whole) - 1, 37):
        path.write_bytes(whole[:cut])
        trace = read_trace(path)
        assert trace["time"].size == 0 and trace["x"].size == 0
    for bad in (tmp_path, 3, None):
        with pytest.raises(InvalidInput, match="read_trace"):
            read_trace(bad)  # type: ignore[arg-type]


def test_every_series_of_a_trace_has_its_own_topic_in_the_bag(tmp_path):
    """Keys that became one topic (``cop left``, ``cop_left``), a topic a point took already (``com``
    beside ``com_position``), a key starting with a digit, a task named with a dash: the last one
    won, was dropped, or failed the whole run's bag after its ``trace.npz`` (and no summary)."""
    pytest.importorskip("rosbags")
    from sotdrake.ros.bag import read_bag, write_bag, write_trace_bag

    t = np.arange(4) * 0.1
    trace = {"time": t, "q": np.zeros((4, 2)), "cop left": np.ones((4, 2)), "cop_left": 2 * np.ones((4, 2)),
             "com_position": np.full((4, 3), 7.0), "com": np.full((4, 3), 6.0), "2nd": np.full(4, 5.0),
             "error_hand-right": np.full((4, 3), 4.0)}
    bag = read_bag(write_trace_bag(tmp_path / "bag", trace, (["a", "b"], np.arange(2))).parent)
    assert sorted(bag) == ["/joint_states", "/sot/_2nd", "/sot/com", "/sot/com_2", "/sot/cop_left", "/sot/cop_left_2",
                           "/sot/error/hand_right"]
    assert [bag[topic][0][1].data[0] for topic in ("/sot/cop_left", "/sot/cop_left_2", "/sot/com_2")] == [1.0, 2.0, 6.0]
    for bad in ({"parent": tmp_path / "missing" / "b"}, {"names": [1, 2]}, {"arrays": {"/a": ["x"] * 4}}, {"frame": 3},
                {"time": t + 2.2e9}):
        arguments = {"directory": bad.get("parent", tmp_path / "b"), "time": bad.get("time", t),
                     "joint_states": (bad.get("names", ["a", "b"]), np.zeros((4, 2))), "arrays": bad.get("arrays"),
                     "frame": bad.get("frame", "world")}
        with pytest.raises(InvalidInput, match="write_bag"):
            write_bag(**arguments)


def test_a_refused_bag_still_leaves_the_runs_summary(tmp_path):
    pytest.importorskip("rclpy")
    builder = DiagramBuilder()
    builder.AddSystem(ConstantVectorSource(np.zeros(1)))
    diagram = builder.Build()
    with pytest.raises(InvalidInput, match="configuration"):
        simulation.write_run(tmp_path / "run", diagram, {"a": 1}, {"time": np.zeros(2)}, graph=False, bag=True)
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["outputs"] == {"trace": str(tmp_path / "run" / "trace.npz")}
    for out in (tmp_path / "run" / "trace.npz", tmp_path / "a\0b"):  # a file, a NUL byte
        with pytest.raises(InvalidInput, match="write_run"):
            simulation.write_run(out, diagram, {}, graph=False)
