"""The rest of the toolbox: gains, TaskPD, the live stack, introspection, tracer, LCM, runner, examples."""

import io
import json
import math
import subprocess
import sys
import time
import uuid
import warnings
from pathlib import Path

import numpy as np
import pytest
from drake import lcmt_robot_state
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.lcm import LcmPublisherSystem

from sotdrake.exceptions import InvalidInput, NotFound, SotWarning, StackError, TaskNotFound
from sotdrake.gains import GainHyperbolic, hyperbolic
from sotdrake.interactive import Runner
from sotdrake.introspection import displayAll, displaySignals, entities, entity, signal, signals_report
from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, gotoNd
from sotdrake.publishing import add_signal_publisher, add_state_publisher
from sotdrake.robot import Robot, add_sot
from sotdrake.scenarios import kinesimple, posture_gaze
from sotdrake.sequencer import attime
from sotdrake.task import TaskPD
from sotdrake.tracing import Tracer

ROOT = Path(__file__).resolve().parents[1]


def test_hyperbolic_gain_matches_sot_core():
    gain = hyperbolic(5.0, 1.0, 8.0, 0.2)  # a = 4, b = 8/4/2 = 1, c = 1, d = 0.2
    assert (gain.a, gain.b, gain.c, gain.d) == (4.0, 1.0, 1.0, 0.2)
    for norm in (0.0, 0.2, 1.0, 10.0):
        assert gain(norm) == pytest.approx(4.0 * 0.5 * (math.tanh(-(norm - 0.2)) + 1) + 1.0)
    assert gain(0.2) == pytest.approx(3.0) and gain(1e3) == pytest.approx(1.0)
    entity_ = GainHyperbolic("g")
    entity_.set(5.0, 1.0, 8.0, 0.2)
    with pytest.raises(InvalidInput):
        entity_.set(1.0, 5.0, 8.0, 0.0)


@pytest.fixture
def stack(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    sot = add_sot(robot)
    metas = {name: MetaTaskKine6d(name, robot, name, op) for name, op in
             (("LF", "left-ankle"), ("RF", "right-ankle"), ("rh", "right-wrist"), ("lh", "left-wrist"))}
    com = MetaTaskKineCom(robot)
    return robot, sot, metas, com, builder.Build()


def test_up_down_and_contacts(stack):
    robot, sot, metas, com, diagram = stack
    context = diagram.CreateDefaultContext()
    sot.addContact(metas["LF"], context)
    sot.addContact("taskRF", context)
    for name in ("taskcom", "taskrh", "tasklh"):
        sot.push(name, context)
    sot.up("tasklh", context)
    assert sot.stack(context) == ["taskcom", "tasklh", "taskrh"]
    sot.down("taskcom", context)
    assert sot.stack(context) == ["tasklh", "taskcom", "taskrh"]
    sot.rmContact("taskLF", context)
    before = (sot.stack(context), sot.contacts(context))
    for bad, error in [(lambda: sot.up("tasklh", context), StackError),
                       (lambda: sot.down("taskrh", context), StackError),
                       (lambda: sot.rmContact("taskRF", context), StackError),  # the last contact
                       (lambda: sot.addContact("taskcom", context), StackError),  # in the stack
                       (lambda: sot.push("taskRF", context), StackError),  # a contact
                       (lambda: sot.addContact("taskfoot", context), TaskNotFound),
                       (lambda: sot.up("taskfoot", context), TaskNotFound)]:
        with pytest.raises(error):
            bad()
        assert (sot.stack(context), sot.contacts(context)) == before
    assert sot.contacts() == [] and sot.stack() == []  # the defaults are untouched


def test_contacts_are_solved_above_the_stack(stack):
    robot, sot, metas, com, diagram = stack
    context = diagram.CreateDefaultContext()
    gotoNd(metas["LF"], metas["LF"].current_pose().translation() + [0.1, 0, 0], "111", 1.0, context)
    sot.push("taskLF", context)  # the stack wants the left foot to move
    sot.addContact("taskRF", context)
    sot.addContact("tasklh", context)
    control = sot.GetOutputPort("control").Eval(sot.GetMyContextFromRoot(context))
    residuals = sot.GetOutputPort("residuals").Eval(sot.GetMyContextFromRoot(context))
    assert len(residuals) == 2 and residuals[0] < 1e-9  # the contacts' level first, exact
    J_rf = robot.dynamic.GetOutputPort("JRF").Eval(robot.dynamic.GetMyContextFromRoot(context))
    assert np.linalg.norm(J_rf @ control) < 1e-9


def test_task_pd_uses_the_error_rate(talos_model):
    task = TaskPD("taskpd", talos_model.nv, dt=0.01)
    task.setBeta(0.5)
    context = task.CreateDefaultContext()
    J = np.eye(3, talos_model.nv)
    task.GetInputPort("jacobian").FixValue(context, J)
    task.GetInputPort("controlGain").FixValue(context, [2.0])
    task.GetInputPort("error").FixValue(context, np.array([1.0, 0.0, -1.0]))
    simulator = Simulator(task, context)
    simulator.AdvanceTo(0.005)  # the tick at t = 0 stored e = (1, 0, -1)
    task.GetInputPort("error").FixValue(simulator.get_mutable_context(), np.array([0.9, 0.1, -1.0]))
    level = task.GetOutputPort("task").Eval(simulator.get_context())
    rate = (np.array([0.9, 0.1, -1.0]) - np.array([1.0, 0.0, -1.0])) / 0.01
    np.testing.assert_allclose(level.reference, -2.0 * np.array([0.9, 0.1, -1.0]) - 0.5 * rate)
    with pytest.raises(InvalidInput):
        task.setBeta(-1.0)
    with pytest.raises(InvalidInput, match="diverge"):  # e_{k+1} = (1 − λdt − β) e_k + β e_{k−1}: a root of size ≥ β
        task.setBeta(1.0)
    assert task._settings_of(simulator.get_context()).beta == 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        task.GetOutputPort("task").Eval(simulator.get_context())  # β = 0.5 < 1 − λ dt / 2 = 0.99: no warning
    task.setBeta(0.995, simulator.get_mutable_context())  # stable for λ dt < 0.01, not at λ = 2 /s, dt = 0.01 s
    task.GetInputPort("error").FixValue(simulator.get_mutable_context(), np.array([0.8, 0.1, -1.0]))
    with pytest.warns(SotWarning, match="oscillates and grows"):
        task.GetOutputPort("task").Eval(simulator.get_context())
    small = TaskPD("small", talos_model.nv, dt=0.01, max_rows=2)  # keeps at most 2 rows
    context = small.CreateDefaultContext()
    small.GetInputPort("jacobian").FixValue(context, J)
    small.GetInputPort("controlGain").FixValue(context, [2.0])
    small.GetInputPort("error").FixValue(context, np.array([1.0, 0.0, -1.0]))
    with pytest.raises(InvalidInput, match="max_rows"):
        Simulator(small, context).AdvanceTo(0.005)
    with pytest.raises(InvalidInput):
        TaskPD("bad", talos_model.nv, dt=0.0)


def test_task_pd_closes_the_loop_with_the_last_ticks_error(talos_model):
    """In a diagram, tick k's command sees e_{k-1}, not e_k (the β term acts): the hand's error
    follows e_{k+1} = e_k - dt λ e_k - β (e_k - e_{k-1}) (first order in dt; the feet held)."""
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    sot = add_sot(robot)
    for name, op in (("RF", "right-ankle"), ("LF", "left-ankle")):
        sot.push(MetaTaskKine6d(name, robot, name, op).task.name)
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist", pd=True)
    gotoNd(hand, hand.current_pose().translation() + [0.01, -0.005, 0.01], "111", 5.0)
    hand.task.setBeta(0.5)
    sot.push(hand.task.name)
    simulator = Simulator(builder.Build())
    context = simulator.get_mutable_context()
    port, dt = hand.feature.GetOutputPort("error"), robot.dt
    errors = []
    for k in range(30):
        errors.append(port.Eval(hand.feature.GetMyContextFromRoot(context)).copy())
        simulator.AdvanceTo((k + 0.5) * dt)
    e = np.array(errors)
    predicted = e[1:-1] - dt * 5.0 * e[1:-1] - 0.5 * (e[1:-1] - e[:-2])
    assert np.abs(0.5 * (e[1:-1] - e[:-2])).max() > 1e-5  # the β term is large …
    np.testing.assert_allclose(e[2:], predicted, rtol=0, atol=1e-7)  # … and acts


def test_introspection(stack):
    robot, sot, metas, com, diagram = stack
    names = entities(diagram)
    assert {"dynamic", "device", "sot", "taskrh", "featurerh", "featurerh_ref", "gainrh"} <= set(names)
    context = diagram.CreateDefaultContext()
    report = signals_report(entity(diagram, "gaincom"), context)
    printed, everything = io.StringIO(), io.StringIO()
    assert displaySignals(entity(diagram, "gaincom"), context, file=printed) is None  # the prompt shows it once
    assert printed.getvalue() == report + "\n"
    displayAll(diagram, context, file=everything)
    assert report in everything.getvalue() and "sot (SOT)" in everything.getvalue()
    assert "out gain" in report and "[1.]" in report and "in  error" in report
    np.testing.assert_allclose(signal(robot.dynamic, "com", context), robot.dynamic.com_at(robot.device.initial_position))
    assert "not connected" in signals_report(metas["rh"].featureDes, context)
    with pytest.raises(NotFound):
        signal(robot.dynamic, "comm", context)
    with pytest.raises(NotFound):
        entity(diagram, "sott")


def test_tracer_csv_and_plot(talos_model, tmp_path):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    add_sot(robot)  # an empty stack: the robot holds still
    com = MetaTaskKineCom(robot)
    tracer = Tracer(builder, 0.01)
    tracer.add(robot.dynamic.GetOutputPort("com"), "com")
    tracer.add(com.task.GetOutputPort("error_norm"), "error")
    with pytest.raises(InvalidInput):
        tracer.add(robot.dynamic.GetOutputPort("com"), "com")
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(0.1)
    csv = tracer.save_csv(simulator.get_context(), tmp_path / "trace.csv")
    header, *rows = csv.read_text().splitlines()
    assert header == "time,com[0],com[1],com[2],error[0]" and len(rows) == 11
    assert tracer.plot(simulator.get_context(), tmp_path / "plot.png").stat().st_size > 1000
    with pytest.raises(InvalidInput):
        tracer.plot(simulator.get_context(), tmp_path / "x.png", ["nothing"])


def test_state_published_at_100_hz_to_another_process(talos_model, tmp_path):
    """Exactly 101 messages 10 ms apart leave the publisher (checked in-process, on an in-memory
    LCM beside the UDP one). Another process receives them over UDP: every message it gets must be
    a whole, ordered state at a multiple of 10 ms, ending on the robot's posture. UDP does not
    retransmit, and on this machine the receiving processes lose a varying part of the stream
    (from none to 60 % of it, on either channel, in repeated runs), so each must get some of it
    (10 states of 101, 3 scopes of 21), not all of it."""
    channel = f"sot_control/state_{uuid.uuid4().hex[:12]}"  # unique: no other run on this host shares it
    subscriber = [sys.executable, str(ROOT / "tests" / "lcm_subscriber.py")]
    # Each listener stops on a "done" message sent after the run (a timeout only if it never comes).
    listener = subprocess.Popen([*subscriber, channel, "state", "600", str(tmp_path / "state.jsonl")], stdout=subprocess.PIPE, text=True)
    scope_listener = subprocess.Popen([*subscriber, channel + "_com", "scope", "600", str(tmp_path / "com.jsonl")],
                                      stdout=subprocess.PIPE, text=True)
    memory = DrakeLcm("memq://")
    sent: list[lcmt_robot_state] = []
    memory.Subscribe(channel, lambda data: sent.append(lcmt_robot_state.decode(data)))
    try:
        assert listener.stdout.readline().strip() == "ready"
        assert scope_listener.stdout.readline().strip() == "ready"
        builder = DiagramBuilder()
        robot = Robot(builder, talos_model)
        add_sot(robot)  # an empty stack: the robot holds still
        add_state_publisher(robot, channel=channel, period=0.01)
        copy = builder.AddSystem(LcmPublisherSystem.Make(channel, lcmt_robot_state, memory, 0.01))
        builder.Connect(builder.GetSubsystemByName("ros_publish_state").get_output_port(), copy.get_input_port())
        add_signal_publisher(robot, robot.dynamic.GetOutputPort("com"), channel + "_com", period=0.05)
        simulator = Simulator(builder.Build())
        simulator.set_target_realtime_rate(1.0)  # as on a robot: no burst for the UDP buffers
        simulator.AdvanceTo(1.0)
        lcm = DrakeLcm()  # same host and URL as the publishers: sent after their last message
        deadline = time.monotonic() + 300
        while (listener.poll() is None or scope_listener.poll() is None) and time.monotonic() < deadline:
            lcm.Publish(channel + "_done", b"")  # (again until heard: UDP may lose it too)
            lcm.Publish(channel + "_com_done", b"")
            time.sleep(0.2)
        assert listener.wait(timeout=10) == 0 and scope_listener.wait(timeout=10) == 0
        messages = [json.loads(line) for line in (tmp_path / "state.jsonl").read_text().splitlines()]
        scopes = [json.loads(line) for line in (tmp_path / "com.jsonl").read_text().splitlines()]
    finally:
        listener.kill()
        scope_listener.kill()
    while memory.HandleSubscriptions(0) > 0:
        pass
    assert [m.utime for m in sent] == list(range(0, 1_000_001, 10_000))  # t = 0, 0.01, …, 1.0
    assert list(sent[0].joint_name[:7]) == [f"base_link_{s}" for s in ("qw", "qx", "qy", "qz", "x", "y", "z")]
    times = np.array([m["utime"] for m in messages])
    assert len(messages) >= 10 and np.all(np.diff(times) > 0) and np.all(times % 10_000 == 0)
    assert messages[0]["names"][:7] == [f"base_link_{s}" for s in ("qw", "qx", "qy", "qz", "x", "y", "z")]
    np.testing.assert_allclose(messages[-1]["values"], talos_model.half_sitting)
    assert len(scopes) >= 3 and np.allclose(scopes[0]["values"], robot.dynamic.com_at(talos_model.half_sitting))


def test_lcm_publishers_take_a_rate_in_ticks_as_the_seed(talos_model):
    """``every=100`` publishes on every 100th tick of the device (sot-core's PeriodicCall behind
    ``addDownsampledSignal(…, 100)``); with 5 ms ticks, at t = 0, 0.5 and 1.0 s."""
    channel = f"sot_control/state_{uuid.uuid4().hex[:12]}"
    memory = DrakeLcm("memq://")
    sent: list[lcmt_robot_state] = []
    memory.Subscribe(channel, lambda data: sent.append(lcmt_robot_state.decode(data)))
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model, dt=5e-3)
    add_sot(robot)
    add_state_publisher(robot, memory, channel, every=100)
    add_signal_publisher(robot, robot.dynamic.GetOutputPort("com"), channel + "_com", memory, every=20)
    scopes: list[bytes] = []
    memory.Subscribe(channel + "_com", scopes.append)
    Simulator(builder.Build()).AdvanceTo(1.0)
    while memory.HandleSubscriptions(0) > 0:
        pass
    assert [m.utime for m in sent] == [0, 500_000, 1_000_000]
    assert len(scopes) == 11  # every 0.1 s from 0 to 1.0
    for kwargs, says in (({"every": 0}, "positive whole number"), ({"every": 2.5}, "positive whole number"),
                         ({"every": 10, "period": 0.05}, "not both"), ({"period": 0.0}, "> 0")):
        with pytest.raises(InvalidInput, match=says):
            add_state_publisher(Robot(DiagramBuilder(), talos_model), memory, channel, **kwargs)


def test_interactive_runner_steps_ticks_and_fires_attime(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    sot = add_sot(robot)
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    gotoNd(hand, hand.current_pose().translation() + [0.05, 0, 0], "111", 5.0)
    attime(0.0105, lambda: sot.push(hand.task.name), "push")
    runner = Runner(builder.Build(), robot.dt)
    assert runner.next() == pytest.approx(0.001)
    assert runner.step(9) == pytest.approx(0.010)
    assert sot.stack(runner.context) == []
    runner.go(0.02)
    assert runner.t == pytest.approx(0.030) and sot.stack(runner.context) == ["taskrh"]
    assert np.linalg.norm(robot.device.position(runner.context) - robot.device.initial_position) > 0
    with pytest.raises(InvalidInput):
        runner.step(-1)


def test_kinesimple_example(tmp_path):
    summary = kinesimple.main(["--duration", "2.5", "--out", str(tmp_path), "--no-meshcat", "--quiet"])
    assert summary["hand_error_m"] < 1e-3 and summary["min_joint_limit_margin_rad"] > 0
    for name in ("trace.npz", "trace.csv", "plots.png", "control_graph.dot", "summary.json"):
        assert (tmp_path / name).is_file()


@pytest.mark.slow
def test_posture_gaze_example_and_its_feed_forward(tmp_path):
    gaze = posture_gaze
    follow = gaze.main(["--duration", "3", "--out", str(tmp_path / "ff"), "--no-meshcat", "--quiet"])
    lag = gaze.main(["--duration", "3", "--out", str(tmp_path / "noff"), "--no-meshcat", "--quiet", "--no-feedforward"])
    assert follow["gaze_error_rad_after_2s_max"] < 1e-3
    assert lag["gaze_error_rad_after_2s_max"] > 20 * follow["gaze_error_rad_after_2s_max"]
    assert follow["max_foot_drift_m"] < 1e-4 and follow["max_com_drift_m"] < 1e-4
    assert (tmp_path / "ff" / "plots.png").is_file()
