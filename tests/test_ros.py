"""ROS 2 (the ``ros2`` extra): ``RosPublish``, ``RosSubscribe``, ``run_command``,
``start_dynamic_graph``, the ``ros_test.py`` port and the bag, on the loopback only.

Each test process has its own ``ROS_DOMAIN_ID`` (one no other test process holds) and
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``. Every wait is for an event (a message, an answer, a
process ending) with a stated, generous time-out; nothing depends on the host's speed: counts are
checked against the simulated time the run reached.
"""

import json
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy", reason='ROS 2 is an optional extra: pip install ".[ros2]"')

from tests.ros_domain import free_domain

os.environ["ROS_DOMAIN_ID"] = str(free_domain())
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray, String

from sotdrake.exceptions import InvalidInput
from sotdrake.ros import (
    RUN_COMMAND_REQUEST,
    RUN_COMMAND_RESPONSE,
    RosNode,
    RosPublish,
    RosSubscribe,
    RunCommandClient,
    read_bag,
)

# A ROS 2 run in other processes; rosidl's parser warns on Python 3.11.
pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::DeprecationWarning:lark")]

ROOT = Path(__file__).resolve().parents[1]
WAIT_S = 120.0  # the longest wait for one message or answer
START_S = 600.0  # the longest wait for the run to start (imports and numba's first compilation)
SETTLE_S = 6.0  # simulated seconds the hand gets after it is pushed
PERIOD_S = 0.1  # 100 ticks of 1 ms: the seed's addDownsampledSignal(…, 100)


def wait_for(condition, timeout: float = WAIT_S, what: str = "an event") -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
        time.sleep(0.02)


def matched(publisher, node, topic: str) -> bool:
    """Both sides of ``topic`` matched: ``publisher`` with a reader, and every reader of ``node`` on
    it with a writer, ``publisher`` when it is the topic's only one (each side discovers the other on
    its own; a reader drops what a writer it has not matched yet sends)."""
    readers = [s for s in node.subscriptions if s.topic_name == topic]
    return publisher.get_subscription_count() > 0 and bool(readers) and all(r.get_publisher_count() > 0 for r in readers)


@pytest.fixture(scope="module")
def observer():
    node = RosNode("test_observer")
    yield node
    node.close()


# --- without the extra ------------------------------------------------------------------------
def test_without_rclpy_the_error_names_the_install_line():
    code = ("import sys; sys.modules['rclpy'] = None\nimport sotdrake\n"
            "try:\n    import sotdrake.ros\nexcept ImportError as e:\n    print('IMPORTERROR', e)\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=START_S, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert 'IMPORTERROR' in result.stdout and 'pip install ".[ros2]"' in result.stdout


# --- mistakes are refused when made ---------------------------------------------------------------
@pytest.mark.parametrize(("kind", "topic", "kwargs", "says"), [
    ("vectr", "/a", {"size": 3}, "unknown signal type"),
    ("vector", "/a", {}, "size="),
    ("vector", "/a", {"size": 0}, "size="),
    ("matrix", "/a", {"shape": (3,)}, "shape="),
    ("vector", "bad topic", {"size": 3}, "bad ROS topic name"),
    ("vector", "/a//b", {"size": 3}, "bad ROS topic name"),
    ("double", "/1a", {}, "bad ROS topic name"),
])
def test_ros_publish_refuses_bad_signals(observer, kind, topic, kwargs, says):
    publisher = RosPublish("p", observer)
    with pytest.raises(InvalidInput, match=says):
        publisher.add(kind, "s", topic, **kwargs)


def test_ros_publish_refuses_a_second_trigger_and_a_repeated_signal(observer):
    publisher = RosPublish("p", observer)
    publisher.add("double", "s", "/s")
    with pytest.raises(InvalidInput, match="already added"):
        publisher.add("double", "s", "/t")
    with pytest.raises(InvalidInput, match="every"):
        publisher.trigger(0, 1e-3)
    publisher.trigger(10, 1e-3)
    with pytest.raises(InvalidInput, match="already set"):
        publisher.trigger(10, 1e-3)


def test_a_topic_ros_refuses_leaves_nothing_behind(observer):
    publisher = RosPublish("p", observer)
    publisher.add("double", "a", "/refused_a")
    with pytest.raises(InvalidInput, match=r"ROS refused|carries rcl_interfaces"):
        publisher.add("vector", "b", "/rosout", size=2)  # (a reserved topic of another type)
    assert list(publisher.signals) == ["a"] and publisher.num_input_ports() == 1
    publisher.add("vector", "b", "/refused_b", size=2)  # (the name is still free)
    with pytest.raises(InvalidInput, match="vector"):
        publisher.add("vector", "c", "/refused_c", size=True)
    subscriber = RosSubscribe("s", observer)
    subscriber.add("double", "x", "/refused_x")
    with pytest.raises(InvalidInput, match="x_age"):
        subscriber.add("double", "x_age", "/refused_y")
    with pytest.raises(InvalidInput, match="distinct"):
        subscriber.add("joint_states", "j", "/refused_j", names=["a", "a"])
    assert list(subscriber.slots) == ["x"] and subscriber.num_output_ports() == 2
    with pytest.raises(InvalidInput, match="depth"):
        RosSubscribe("t", observer, depth=-1)


def test_ros_publisher_rate_in_ticks_or_in_seconds(observer, talos_model):
    """The seed's addDownsampledSignal(…, 100) is every 100 ticks; a period in seconds must be a
    whole number of ticks."""
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake.robot import Robot
    from sotdrake.ros import add_ros_publisher

    robot = Robot(DiagramBuilder(), talos_model, dt=1e-3)
    ticks = add_ros_publisher(robot, node=observer, every=100, joint_states=None)
    assert (ticks.state.every, ticks.state.period) == (100, pytest.approx(0.1))
    robot = Robot(DiagramBuilder(), talos_model, dt=1e-3)
    seconds = add_ros_publisher(robot, node=observer, period=0.05, joint_states=None)
    assert seconds.state.every == 50
    for kwargs, says in (({"period": 0.0505}, "whole number of ticks"), ({"period": 0.1, "every": 100}, "not both"),
                         ({"period": -1.0}, "> 0")):
        with pytest.raises(InvalidInput, match=says):
            add_ros_publisher(Robot(DiagramBuilder(), talos_model, dt=1e-3), node=observer, joint_states=None, **kwargs)
    robot = Robot(DiagramBuilder(), talos_model, dt=1e-3)
    systems = robot.builder.GetSystems()
    for kwargs in ({"every": 0}, {"every": 2.5}, {"every": True}, {"topic": "/a b"}, {"joint_states": "/x y"}):
        with pytest.raises(InvalidInput):  # (refused before anything is added: the retry below works)
            add_ros_publisher(robot, node=observer, **kwargs)
        assert robot.builder.GetSystems() == systems
    add_ros_publisher(robot, node=observer, every=100)


def test_ros_publish_kinds_reach_another_node(observer):
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    from sotdrake.ros import RosNode

    sender = RosNode("test_sender")
    try:
        builder = DiagramBuilder()
        publish = builder.AddSystem(RosPublish("kinds", sender))
        values = {"v": np.arange(5.0), "m": np.arange(6.0), "h": np.eye(4).ravel(), "d": np.array([2.5])}
        kinds = {"v": ("vector", {"size": 5}), "m": ("matrix", {"shape": (2, 3)}), "h": ("matrixHomo", {}),
                 "d": ("double", {})}
        got: dict[str, list] = {k: [] for k in values}
        for name, (kind, kwargs) in kinds.items():
            port = publish.add(kind, name, f"/test_kinds/{name}", **kwargs)
            source = builder.AddSystem(ConstantVectorSource(values[name]))
            builder.Connect(source.get_output_port(), port)
            observer.node.create_subscription(Float64 if kind == "double" else Float64MultiArray,
                                              f"/test_kinds/{name}", got[name].append, 100)
        publish.trigger(10, 1e-3)
        diagram = builder.Build()
        wait_for(lambda: all(matched(s.publisher, observer.node, s.topic) for s in publish.signals.values()),
                 what="both sides of each topic to match")
        Simulator(diagram).AdvanceTo(0.05)  # publishes at t = 0, 0.01, …, 0.05
        wait_for(lambda: all(len(g) == 6 for g in got.values()), what="6 messages of each kind")
        assert publish.published == 6
        assert list(got["v"][-1].data) == values["v"].tolist()
        assert [d.size for d in got["m"][-1].layout.dim] == [2, 3] and list(got["m"][-1].data) == values["m"].tolist()
        assert [d.size for d in got["h"][-1].layout.dim] == [4, 4]
        assert got["d"][-1].data == 2.5
    finally:
        sender.close()


def test_ros_subscribe_holds_the_default_then_the_last_value(observer, caplog):
    from sotdrake.ros import RosNode

    subscribe = RosSubscribe("sub", observer)
    port = subscribe.add("vector", "target", "/test_subscribe/target", default=(1.0, 2.0, 3.0), size=3)
    joints = subscribe.add("joint_states", "q", "/test_subscribe/joints", names=["b", "a"])
    context = subscribe.CreateDefaultContext()
    with caplog.at_level("WARNING", logger="sotdrake.ros"):
        assert port.Eval(context).tolist() == [1.0, 2.0, 3.0]
        assert port.Eval(context).tolist() == [1.0, 2.0, 3.0]
    assert sum("holding the default" in r.message for r in caplog.records) == 1
    assert math.isinf(subscribe.GetOutputPort("target_age").Eval(context)[0])
    sender = RosNode("test_subscribe_sender")
    try:
        pub = sender.node.create_publisher(Float64MultiArray, "/test_subscribe/target", 10)
        pub_joints = sender.node.create_publisher(JointState, "/test_subscribe/joints", 10)
        wait_for(lambda: matched(pub, observer.node, "/test_subscribe/target")
                 and matched(pub_joints, observer.node, "/test_subscribe/joints"), what="the subscriptions to match")
        pub.publish(Float64MultiArray(data=[1.0, 2.0]))  # wrong size: dropped
        pub.publish(Float64MultiArray(data=[4.0, 5.0, 6.0]))
        pub_joints.publish(JointState(name=["a", "b", "c"], position=[1.0, 2.0, 3.0]))
        wait_for(lambda: subscribe.count("target") == 1 and subscribe.count("q") == 1, what="both messages")
        context = subscribe.CreateDefaultContext()
        assert port.Eval(context).tolist() == [4.0, 5.0, 6.0]
        assert joints.Eval(context).tolist() == [2.0, 1.0]
        assert 0 <= subscribe.GetOutputPort("target_age").Eval(context)[0] < WAIT_S
    finally:
        sender.close()
    with pytest.raises(InvalidInput, match="names="):
        subscribe.add("joint_states", "j2", "/j2")
    with pytest.raises(InvalidInput, match="default"):
        subscribe.add("vector", "t2", "/t2", default=(1.0,), size=3)


def test_a_subscribed_pose_holds_a_unit_quaternion(observer):
    """A pose's quaternion is normalised; one that is not a rotation (norm 0, or far from 1) is
    dropped, and a default must hold a unit one (a zero quaternion passed through before)."""
    from geometry_msgs.msg import PoseStamped

    from sotdrake.ros import RosNode

    subscribe = RosSubscribe("sub_pose", observer)
    port = subscribe.add("pose", "target", "/test_subscribe/pose")
    for default in ((0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0)):
        with pytest.raises(InvalidInput, match="unit quaternion"):
            subscribe.add("pose", "other", "/test_subscribe/other", default=default)
    sender = RosNode("test_subscribe_pose_sender")
    try:
        pub = sender.node.create_publisher(PoseStamped, "/test_subscribe/pose", 10)
        wait_for(lambda: matched(pub, observer.node, "/test_subscribe/pose"), what="the subscription to match")
        for w, x, count in ((0.0, 0.0, 0), (0.9, 1.2, 1), (0.0, 0.0, 1)):  # (zero: dropped; norm 1.5: normalised)
            message = PoseStamped()
            message.pose.position.x, message.pose.orientation.w, message.pose.orientation.x = 0.5, w, x
            pub.publish(message)
            if count:
                wait_for(lambda count=count: subscribe.count("target") == count, what="the pose")
        time.sleep(0.2)
        assert subscribe.count("target") == 1
        np.testing.assert_allclose(port.Eval(subscribe.CreateDefaultContext()), [0.5, 0.0, 0.0, 0.6, 0.8, 0.0, 0.0])
    finally:
        sender.close()


# --- the client's handshake -------------------------------------------------------------------------
class LossyRun:
    """Stands for a run's services: drops its first ``lost`` requests (as a reader not yet matched
    with the client's publisher would) and answers each of the others ``repeat`` times (the repeats
    are late answers) with the simulated time 0."""

    def __init__(self, lost: int, repeat: int = 1):
        from std_srvs.srv import Empty

        from sotdrake.ros import START_SERVICE

        self.ros, self.lost, self.repeat, self.seen, self.answered = RosNode("test_lossy_run"), lost, repeat, [], 0
        node = self.ros.node
        self.responses = node.create_publisher(String, RUN_COMMAND_RESPONSE, 1000)
        node.create_subscription(String, RUN_COMMAND_REQUEST, self._request, 1000)
        node.create_service(Empty, START_SERVICE, lambda request, response: response)

    def _request(self, message):
        request = json.loads(message.data)
        self.seen.append(request["command"])
        if len(self.seen) > self.lost:
            for _ in range(self.repeat):
                self.responses.publish(String(data=json.dumps({"id": request["id"], "ok": True, "answer": "0.0000"})))
                self.answered += 1


@pytest.mark.parametrize("lost", [0, 3])
def test_the_handshake_outlasts_lost_first_requests(observer, lost, monkeypatch):
    from sotdrake.ros.client import HELLO

    heard = []  # (every answer the client's subscription handled)
    respond = RunCommandClient._response
    monkeypatch.setattr(RunCommandClient, "_response", lambda self, message: (respond(self, message), heard.append(1)))
    run = LossyRun(lost, repeat=2)
    client = RunCommandClient(observer, WAIT_S)
    try:  # (both sides of both topics matched first: the only requests lost are the run's drops)
        wait_for(lambda: matched(client.requests, run.ros.node, RUN_COMMAND_REQUEST)
                 and matched(run.responses, observer.node, RUN_COMMAND_RESPONSE), what="the topics")
        client.wait()
        assert len(run.seen) >= lost + 1 and set(run.seen) == {HELLO}
        assert client.command("time()") == {"id": f"{client._prefix}-{client._count}", "ok": True, "answer": "0.0000"}
        wait_for(lambda: len(run.seen) == client._count and len(heard) == run.answered, what="every request and answer")
        assert client._answers == {} and client._pending == set()  # (the late answers were dropped)
    finally:
        client.close()
        run.ros.close()


def test_the_handshake_says_what_did_not_answer(observer):
    from sotdrake.exceptions import SotError

    client = RunCommandClient(observer, WAIT_S)
    run = None
    try:  # (no run: once the graph has forgotten the endpoints of any run closed before)
        wait_for(lambda: observer.node.count_subscribers(RUN_COMMAND_REQUEST) == observer.node.count_publishers(RUN_COMMAND_RESPONSE)
                 == 0 and not client.starter.service_is_ready(), what="the runs closed before to be gone")
        with pytest.raises(SotError, match=r"not available after 0\.3 s"):
            client.wait(0.3)
        run = LossyRun(10**9)
        wait_for(lambda: client.ready() and matched(client.requests, run.ros.node, RUN_COMMAND_REQUEST), what="the run")
        with pytest.raises(SotError, match=r"no answer to 'time\(\)' within 3 s"):
            client.wait(3.0)
        wait_for(lambda: len(run.seen) >= 2, what="the request sent again")
        assert client._answers == {} and client._pending == set()
    finally:
        client.close()
        if run is not None:
            run.ros.close()


@pytest.mark.parametrize("closed", ["client", "node"])
@pytest.mark.parametrize("call", ["command", "start"])
def test_a_call_raises_at_once_when_its_client_or_node_is_closed(call, closed):
    """Nothing answers (no run, no start service): closing the client, or shutting its node down,
    from another thread ends the call with an error, not at its time-out."""
    from sotdrake.exceptions import SotError

    node = RosNode("test_client_node")
    client = RunCommandClient(node, WAIT_S)
    reason = r"$" if closed == "client" else r" \(its ROS node test_client_node is shut down\)$"
    try:
        threading.Timer(0.5, client.close if closed == "client" else node.close).start()
        started = time.monotonic()
        with pytest.raises(SotError, match=f"{call}: the client is closed{reason}"):
            client.command("time()") if call == "command" else client.start()
        assert time.monotonic() - started < WAIT_S / 2  # (not its time-out)
    finally:
        client.close()
        node.close()


def test_the_client_refuses_bad_arguments_and_a_closed_client(observer):
    from sotdrake.exceptions import SotError

    def entities():
        return [len(list(kind)) for kind in (observer.node.publishers, observer.node.subscriptions, observer.node.clients)]

    before = entities()
    for timeout in (-1.0, math.nan, math.inf, "5", True, None, [1.0]):
        with pytest.raises(InvalidInput, match="timeout"):
            RunCommandClient(observer, timeout)  # type: ignore[arg-type]
    with pytest.raises(InvalidInput, match="node"):
        RunCommandClient("test_observer", 1.0)  # type: ignore[arg-type]
    client = RunCommandClient(observer, 1.0)
    for call in (lambda: client.wait(-1), lambda: client.command("time()", math.nan), lambda: client.start(1e7)):
        with pytest.raises(InvalidInput, match="timeout"):
            call()
    for line in (None, 5, b"time()", ["time()"]):
        with pytest.raises(InvalidInput, match="line"):
            client.command(line)  # type: ignore[arg-type]
    assert client._count == 0  # (nothing sent)
    client.close()
    client.close()
    assert not client.ready()
    for name, call in (("wait", client.wait), ("command", lambda: client.command("time()")), ("start", client.start)):
        with pytest.raises(SotError, match=f"{name}: the client is closed"):
            call()
    assert entities() == before


# --- the tutorial over ROS: talos_appli.py --ros --bag, driven by ros_test.py ----------------------
#: run_command lines that must be refused, changing nothing, while the run goes on.
HOSTILE = [
    "__import__('os').system('touch /tmp/sotdrake_pwned')",
    "import os",
    "eval('1+1')",
    "exec('print(1)')",
    "open('/etc/passwd').read()",
    "sot.__class__",
    "sot.push(__import__('os'))",
    "lambda: 0",
    "[x for x in ()]",
    "sot.push('nosuchtask')",
    "sot.push('taskrh')",  # already in the stack
    "taskRH.gain.setConstant(-1)",
    "os.system('ls')",
    "getattr(sot, 'push')('taskrh')",
    "sot.push(taskRH.task.name)",
    "x = 1",
    "sot.push(*['taskrh'])",
    "device.set_position((0,))",
    "'a' * 10**9",
    "f'{sot}'",
    "sot.clear(); import os",
    "sot.push('taskrh')\nimport os",
    "taskRH.selec('1111111')",
    "gotoNd(taskRH, (1, 2), '111')",
    "sot.a.b.c.d()",
    "",
    "x" * 5000,
    '{"id": "bad", "cmd": "sot.clear()"}',
]
#: What must not change.
PROBES = ["stack()", "taskRH.gain.coefficients()", "taskCom.gain.coefficients()",
          "contactLF.gain.coefficients()", "contactRF.gain.coefficients()", "sot.contacts()"]


def ask(client: RunCommandClient, line: str) -> str:
    answer = client.command(line)
    assert answer["ok"], f"{line}: {answer.get('error')}"
    return answer["answer"]


@pytest.fixture(scope="module")
def ros_run(tmp_path_factory, observer):
    """The run and what another process saw of it."""
    work = tmp_path_factory.mktemp("ros")
    out, log = work / "out", work / "appli.log"
    env = dict(os.environ, PYTHONPATH=str(ROOT), XDG_RUNTIME_DIR=str(work))
    seen: dict[str, list] = {"state": [], "joints": []}
    lock = threading.Lock()

    def keep(key):
        def store(message):
            with lock:
                seen[key].append(message)
        return store

    state_sub = observer.node.create_subscription(Float64MultiArray, "/sot_control/state", keep("state"), 10_000)
    joint_sub = observer.node.create_subscription(JointState, "/joint_states", keep("joints"), 10_000)
    raw_answers: list[dict] = []
    raw_sub = observer.node.create_subscription(String, RUN_COMMAND_RESPONSE,
                                                lambda m: raw_answers.append(json.loads(m.data)), 1000)
    raw_pub = observer.node.create_publisher(String, RUN_COMMAND_REQUEST, 1000)
    with open(log, "w") as log_file:
        appli = subprocess.Popen([sys.executable, str(ROOT / "diagrams" / "talos_appli.py"), "--ros", "--bag",
                                  "--no-meshcat", "--rate", "2", "--out", str(out)],
                                 cwd=work, env=env, stdout=log_file, stderr=subprocess.STDOUT)
    result: dict = {"out": out, "log": log}
    try:
        client = RunCommandClient(observer, WAIT_S)
        client.wait(START_S)
        wait_for(lambda: state_sub.get_publisher_count() > 0 and joint_sub.get_publisher_count() > 0,
                 what="the state publishers")
        # Held until started: the time stays 0 and nothing is published.
        result["time_before_start"] = float(ask(client, "time()"))
        time.sleep(0.5)
        result["time_before_start_later"] = float(ask(client, "time()"))
        result["published_before_start"] = len(seen["state"])
        # The seed's test.py, in its own process: appli lines, start, hand; then SETTLE_S s.
        driver = subprocess.run([sys.executable, str(ROOT / "diagrams" / "ros_test.py"), "--settle", str(SETTLE_S),
                                 "--timeout", str(WAIT_S)], cwd=work, env=env, capture_output=True, text=True,
                                timeout=START_S)
        result["driver"] = driver
        assert driver.returncode == 0, driver.stdout + driver.stderr
        # Hostile commands: refused, nothing changed, the run goes on.
        before = [ask(client, p) for p in PROBES]
        t0 = float(ask(client, "time()"))
        result["hostile"] = [(line, client.command(line)) for line in HOSTILE]
        result["probes"] = (before, [ask(client, p) for p in PROBES])
        deadline = time.monotonic() + WAIT_S
        while float(ask(client, "time()")) < t0 + 0.5:  # the run goes on
            assert time.monotonic() < deadline, "the run stopped after the hostile commands"
            time.sleep(0.05)
        raw_pub.publish(String(data="{not json"))
        wait_for(lambda: any(a.get("id") is None for a in raw_answers), what="the answer to a bad request")
        result["bad_request"] = next(a for a in raw_answers if a.get("id") is None)
        ask(client, "stop()")
        appli.wait(START_S)
        result["returncode"] = appli.returncode
        summary = json.loads((out / "summary.json").read_text())
        result["summary"] = summary
        expected = math.floor(summary["duration_s"] / PERIOD_S + 1e-9) + 1
        result["expected"] = expected
        wait_for(lambda: len(seen["state"]) >= expected - 1 and len(seen["joints"]) >= expected - 1,
                 what=f"{expected - 1} state messages")
        time.sleep(0.5)  # any message still in flight
        with lock:
            result["state"], result["joints"] = list(seen["state"]), list(seen["joints"])
        client.close()
        yield result
    except Exception as error:  # (the setup's, with what the run printed)
        raise AssertionError(f"{error}\n--- the run's log, its end ---\n{log.read_text()[-4000:]}") from error
    finally:
        if appli.poll() is None:
            appli.kill()
            appli.wait()
        for sub in (state_sub, joint_sub, raw_sub):
            observer.node.destroy_subscription(sub)
        observer.node.destroy_publisher(raw_pub)


def test_start_dynamic_graph_starts_the_run(ros_run):
    assert ros_run["time_before_start"] == 0.0 == ros_run["time_before_start_later"]
    assert ros_run["published_before_start"] == 0
    assert ros_run["returncode"] == 0, ros_run["log"].read_text()
    assert ros_run["summary"]["duration_s"] > SETTLE_S


def test_state_arrives_at_the_configured_period(ros_run):
    states, expected = ros_run["state"], ros_run["expected"]
    assert abs(len(states) - expected) <= 1, (len(states), expected)
    assert all(len(m.data) == 39 for m in states)


def test_joint_states_equal_the_trace(ros_run):
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake import talos
    from sotdrake.ros import joint_coordinates

    names, indices = joint_coordinates(talos(DiagramBuilder()).model.plant)
    trace = np.load(ros_run["out"] / "trace.npz")
    times = trace["time"]
    joints = ros_run["joints"]
    assert abs(len(joints) - ros_run["expected"]) <= 1
    stamps = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in joints])
    assert np.allclose(np.diff(stamps), PERIOD_S, atol=1e-9)
    matched = 0
    for stamp, message in zip(stamps, joints, strict=True):
        assert list(message.name) == names
        k = np.flatnonzero(np.abs(times - stamp) < 1e-9)
        if stamp > 0:
            assert k.size == 1, stamp
            assert np.array_equal(np.asarray(message.position), trace["q"][k[0]][indices])
            matched += 1
    assert matched >= len(joints) - 1


def test_run_command_refuses_hostile_code(ros_run):
    assert len(HOSTILE) >= 20
    accepted = [(line, answer) for line, answer in ros_run["hostile"] if answer["ok"]]
    assert not accepted
    assert all(answer.get("error") for _, answer in ros_run["hostile"])
    before, after = ros_run["probes"]
    assert before == after
    assert not Path("/tmp/sotdrake_pwned").exists()
    assert ros_run["bad_request"]["ok"] is False and "bad request" in ros_run["bad_request"]["error"]


def test_ros_test_port_moves_the_hand(ros_run):
    driver = ros_run["driver"].stdout
    assert "...done with initialize SoT" in driver and "dynamic graph started" in driver
    summary = ros_run["summary"]
    assert summary["final_stack"] == ["taskcontactRF", "taskcontactLF", "taskcom", "taskrh"]
    assert summary["hand_error_m"] < 5e-3
    assert summary["max_foot_drift_m"] < 1e-4
    assert summary["max_com_drift_m"] < 1e-4


def test_bag_reads_back_equal_to_the_trace(ros_run):
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake import talos
    from sotdrake.ros import joint_coordinates

    names, indices = joint_coordinates(talos(DiagramBuilder()).model.plant)
    bag = ros_run["out"] / "run"
    assert (bag / "run.mcap").is_file()
    trace = np.load(ros_run["out"] / "trace.npz")
    times = trace["time"][::10]
    messages = read_bag(bag)
    expected_topics = {"/joint_states", "/sot/error/taskrh", "/sot/error/taskcom", "/sot/error/taskcontactRF",
                       "/sot/error/taskcontactLF", "/sot/hand", "/sot/com", "/sot/target/rh"}
    assert expected_topics <= set(messages)
    for topic in expected_topics:
        assert len(messages[topic]) == times.size, topic
        assert [ns for ns, _ in messages[topic]] == [round(t * 1e9) for t in times], topic
    joints = messages["/joint_states"]
    assert joints[0][1].__msgtype__ == "sensor_msgs/msg/JointState" and list(joints[0][1].name) == names
    assert np.array_equal(np.array([m.position for _, m in joints]), trace["q"][::10][:, indices])
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in joints] == [ns for ns, _ in joints]
    errors = messages["/sot/error/taskrh"]
    assert errors[0][1].__msgtype__ == "std_msgs/msg/Float64MultiArray"
    assert np.array_equal(np.array([m.data for _, m in errors]), trace["error_taskrh"][::10].reshape(times.size, -1))
    com = np.array([[m.point.x, m.point.y, m.point.z] for _, m in messages["/sot/com"]])
    assert messages["/sot/com"][0][1].__msgtype__ == "geometry_msgs/msg/PointStamped"
    assert np.array_equal(com, trace["com_position"][::10])
    target = np.array([[m.point.x, m.point.y, m.point.z] for _, m in messages["/sot/target/rh"]])
    assert np.array_equal(target, trace["target_rh"][::10])  # (the target in force at each sample)
    assert np.array_equal(target[-1], [0.5, -0.2, 1.0]) and "/sot/target_rh" not in messages


# --- towards a real robot: commands and the watchdog ---------------------------------------------
def test_command_publishers_send_positions_torques_gains_and_references(observer):
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake import talos
    from sotdrake.ros import JointCommandPublisher, RosNode, TorqueCommandPublisher

    plant = talos(DiagramBuilder()).model.plant
    sender = RosNode("test_commands")
    try:
        with pytest.raises(InvalidInput, match="unknown joints"):
            JointCommandPublisher(plant, joints=["no_such_joint"], node=sender)
        with pytest.raises(InvalidInput, match="kp"):
            TorqueCommandPublisher(plant, kp=-1.0, kd=1.0, node=sender)
        arm = ["arm_right_1_joint", "arm_right_4_joint"]
        positions = JointCommandPublisher(plant, "/test_commands/positions", joints=arm, node=sender)
        torques = TorqueCommandPublisher(plant, kp=300.0, kd=np.arange(plant.num_actuators(), dtype=float),
                                         prefix="/test_commands/lfc", node=sender)
        got: dict[str, list] = {k: [] for k in ("positions", "feedforward", "reference", "gains")}
        topics = {"positions": "/test_commands/positions", "feedforward": "/test_commands/lfc/feedforward",
                  "reference": "/test_commands/lfc/reference", "gains": "/test_commands/lfc/gains"}
        for key, topic in topics.items():
            observer.node.create_subscription(Float64MultiArray, topic, got[key].append, 10)
        wait_for(lambda: matched(positions.publisher, observer.node, topics["positions"])
                 and all(matched(torques.publishers[k], observer.node, topics[k]) for k in topics if k != "positions"),
                 what="the subscriptions")
        q = np.arange(plant.num_positions(), dtype=float)
        context = positions.CreateDefaultContext()
        positions.position.FixValue(context, q)
        positions.send(context)
        na, x = plant.num_actuators(), np.arange(plant.num_positions() + plant.num_velocities(), dtype=float)
        context = torques.CreateDefaultContext()
        torques.torque.FixValue(context, np.full(na, 2.0))
        torques.state.FixValue(context, x)
        torques.send(context)
        wait_for(lambda: all(got.values()), what="the four messages")
        joints = [plant.GetJointByName(j) for j in arm]
        assert list(got["positions"][0].data) == [q[j.position_start()] for j in joints]
        assert list(got["feedforward"][0].data) == [2.0] * na
        assert list(got["gains"][0].data) == [300.0] * na + list(range(na))
        assert list(got["reference"][0].data) == x[torques.q_indices].tolist() + x[torques.v_indices].tolist()
    finally:
        sender.close()


def test_watchdog_holds_the_command_without_joint_states(caplog):
    from sotdrake.ros import JointStateWatchdog

    with pytest.raises(InvalidInput, match="timeout"):
        JointStateWatchdog(2, timeout=0.0, dt=1e-3)
    watchdog = JointStateWatchdog(2, timeout=0.05, dt=1e-3, initial=(7.0, 8.0))
    context = watchdog.CreateDefaultContext()
    out, healthy = watchdog.GetOutputPort("command"), watchdog.GetOutputPort("healthy")

    def tick(command, age):
        watchdog.command.FixValue(context, np.asarray(command, dtype=float))
        watchdog.age.FixValue(context, [age])
        context.SetDiscreteState(watchdog.EvalUniquePeriodicDiscreteUpdate(context))

    watchdog.command.FixValue(context, [1.0, 2.0])
    watchdog.age.FixValue(context, [math.inf])  # nothing received yet: the initial command
    assert out.Eval(context).tolist() == [7.0, 8.0] and healthy.Eval(context)[0] == 0.0
    tick([1.0, 2.0], 0.01)
    assert out.Eval(context).tolist() == [1.0, 2.0] and healthy.Eval(context)[0] == 1.0
    with caplog.at_level("WARNING", logger="sotdrake.ros"):
        tick([3.0, 4.0], 0.2)  # stale: the last fresh command is held
        assert out.Eval(context).tolist() == [1.0, 2.0] and healthy.Eval(context)[0] == 0.0
        tick([5.0, 6.0], 0.3)
        assert out.Eval(context).tolist() == [1.0, 2.0]
        tick([5.0, 6.0], 0.0)
        assert out.Eval(context).tolist() == [5.0, 6.0]
    messages = [r.message for r in caplog.records]
    assert sum("holding the command" in m for m in messages) == 1 and sum("are back" in m for m in messages) == 1


def test_any_script_writes_its_trace_as_a_bag(tmp_path):
    """``--bag`` on a script of ``diagrams/`` (kinesimple: no ROS run, the trace written by
    ``write_run``): ``run/run.mcap`` holds every trace sample of ``q`` as ``/joint_states``, named by
    the script's robot, and each task's error."""
    from sotdrake.ros import joint_coordinates
    from sotdrake.scenarios import kinesimple

    out = tmp_path / "out"
    run = subprocess.run([sys.executable, str(ROOT / "diagrams" / "kinesimple.py"), "--bag", "--no-meshcat", "--quiet",
                          "--duration", "0.2", "--out", str(out)], cwd=tmp_path, capture_output=True, text=True,
                         timeout=600, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert run.returncode == 0, run.stderr
    trace = np.load(out / "trace.npz")
    messages = read_bag(out / "run")
    names, indices = joint_coordinates(kinesimple.build_diagram().diagram.GetSubsystemByName("dynamic").plant)
    joints = messages["/joint_states"]
    assert len(joints) == trace["time"].size and list(joints[0][1].name) == names
    assert np.array_equal(np.array([m.position for _, m in joints]), trace["q"][:, indices])
    assert any(topic.startswith("/sot/error/") for topic in messages)
    assert json.loads((out / "summary.json").read_text())["outputs"]["bag"].endswith("run.mcap")


def test_a_dynamic_scripts_bag_holds_its_torques_and_wrenches(tmp_path):
    """``talos_dynamics.py --bag``: the state ``x``'s positions as ``/joint_states``, and the other
    series of the trace (torques, contact wrenches, CoM) as arrays, one message per sample."""
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, str(ROOT / "diagrams" / "talos_dynamics.py"), "--scenario", "stand", "--device",
                          "dynsimu", "--duration", "0.02", "--bag", "--no-meshcat", "--quiet", "--out", str(out)],
                         cwd=tmp_path, capture_output=True, text=True, timeout=600, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert run.returncode == 0, run.stderr
    trace = np.load(out / "trace.npz")
    messages = read_bag(out / "run")
    assert {"/joint_states", "/sot/torque", "/sot/wrenches", "/sot/com"} <= set(messages)
    assert all(len(messages[topic]) == trace["time"].size for topic in ("/joint_states", "/sot/torque", "/sot/wrenches"))
    assert np.array_equal(np.array([m.data for _, m in messages["/sot/wrenches"]]), trace["wrenches"])
