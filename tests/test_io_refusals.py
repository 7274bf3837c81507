"""Traces, bags, the live channel and its connection file: a bad input or a broken file is refused
as a :class:`SotError` (or answered, on the live channel) and leaves what exists as it was; a run
stopped halfway keeps what it recorded."""

from __future__ import annotations

import json
import os
import socket
import threading
import time
import types

import numpy as np
import pytest
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
def test_a_live_run_whose_trace_cannot_be_written_stops_and_writes_its_files(tmp_path):
    from sotdrake.live.runner import run_live

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
