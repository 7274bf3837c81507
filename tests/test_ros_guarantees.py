"""ROS 2 bridge guarantees: no ``run_command`` request lost in a burst, ``status()`` of a held graph,
``/clock`` beside simulated-time stamps, what ``RosSubscribe`` drops and keeps, and bags that hold
every series (the target in force, fully qualified topics, any shape).

Every wait is for an event (a message, an answer, a log record) with a generous time-out; nothing
depends on the host's speed."""

import json
import logging
import threading

import numpy as np
import pytest

pytest.importorskip("rclpy", reason='ROS 2 is an optional extra: pip install ".[ros2]"')

from geometry_msgs.msg import PoseStamped
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from rclpy.duration import Duration
from rclpy.qos import QoSProfile
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String

from sotdrake.exceptions import SotError
from sotdrake.ros import (
    RUN_COMMAND_REQUEST,
    RUN_COMMAND_RESPONSE,
    JointStatePublisher,
    RosNode,
    RosServices,
    RosSubscribe,
    read_bag,
    write_bag,
    write_trace_bag,
)
from tests.test_ros import matched, observer, wait_for  # noqa: F401  (its ROS_DOMAIN_ID and LOCALHOST too)

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::DeprecationWarning:lark")]

WAIT_S = 120.0
BURST = 3000  # requests at once: three times the reader's former depth


# --- run_command: a burst, and status() while held ---------------------------------------------------
@pytest.fixture()
def held_run():
    """A live run of a small diagram with its ROS services, held (before ``start_dynamic_graph``),
    its commands applied by :meth:`RosServices.wait_for_start` in a thread."""
    from sotdrake.live.runner import LiveRun

    builder = DiagramBuilder()
    builder.AddSystem(ConstantVectorSource([1.0]))
    live = LiveRun(builder.Build(), 1e-3)
    node = RosNode("test_guarantees_run")
    services = RosServices(live, node, hold=True)
    waiting = threading.Thread(target=services.wait_for_start, daemon=True)
    waiting.start()
    try:
        yield live, services
    finally:
        services._start(None, None)
        waiting.join(WAIT_S)
        services.close(flush_s=1.0)
        live.server.close()
        node.close()


def test_a_burst_of_requests_is_answered_in_full(observer, held_run):  # noqa: F811
    """Requests that arrive while the run cannot take them wait in the reader (KEEP_ALL): none is
    overwritten, each gets its answer."""
    live, services = held_run
    gate = threading.Event()
    handle = live.server._handle_line

    def held_back(client, ident, line):  # (the run takes nothing until the whole burst is delivered)
        gate.wait(WAIT_S)
        handle(client, ident, line)

    live.server._handle_line = held_back
    answers: set = set()
    responses = observer.node.create_subscription(String, RUN_COMMAND_RESPONSE,
                                                  lambda m: answers.add(json.loads(m.data)["id"]), 100_000)
    requests = observer.node.create_publisher(String, RUN_COMMAND_REQUEST, QoSProfile(depth=2 * BURST))
    try:
        wait_for(lambda: matched(requests, services.ros.node, RUN_COMMAND_REQUEST)
                 and matched(services.responses, observer.node, RUN_COMMAND_RESPONSE), WAIT_S, "the topics")
        for k in range(BURST):
            requests.publish(String(data=json.dumps({"id": f"burst-{k}", "command": "time()"})))
        assert requests.wait_for_all_acked(Duration(seconds=WAIT_S))  # (in the run's reader, untaken)
        gate.set()
        wait_for(lambda: len(answers) == BURST, WAIT_S, f"{BURST} answers")
        assert answers == {f"burst-{k}" for k in range(BURST)}
        assert live.server.counts.received == BURST
    finally:
        gate.set()
        observer.node.destroy_subscription(responses)
        observer.node.destroy_publisher(requests)


def test_status_of_a_held_graph_says_held_not_late(held_run):
    live, services = held_run
    live._wall0 -= 1000.0  # (as if held for 1000 s)
    ok, text = live.server.handle(b"status()", live.context)
    report = json.loads(text)
    assert ok and report["held"] is True
    assert report["lag_ticks"] == report["max_lag_ticks"] == 0 and report["wall"] == 0.0 and report["t"] == 0.0
    services.started.set()
    wait_for(lambda: not services.held, WAIT_S, "the start")
    assert json.loads(live.server.handle(b"status()", live.context)[1])["held"] is False


# --- /clock beside stamps of simulated time -----------------------------------------------------------
def test_joint_states_come_with_their_time_on_clock(observer):  # noqa: F811
    """Each stamped tick's time is published on /clock first, once, with the same stamp (a node run
    with ``use_sim_time`` reads that topic: following it is rclpy's part)."""
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import RevoluteJoint, SpatialInertia
    from rosgraph_msgs.msg import Clock

    plant = MultibodyPlant(0.0)
    body = plant.AddRigidBody("link", SpatialInertia.SolidSphereWithMass(1.0, 0.1))
    plant.AddJoint(RevoluteJoint("hinge", plant.world_frame(), body.body_frame(), [0.0, 0.0, 1.0]))
    plant.Finalize()
    sender = RosNode("test_clock_sender")
    readers: list = []
    try:
        builder = DiagramBuilder()
        joints = builder.AddSystem(JointStatePublisher(plant, "/test_clock/joints", node=sender))
        builder.Connect(builder.AddSystem(ConstantVectorSource([0.5])).get_output_port(), joints.state)
        joints.trigger(10, 1e-3)
        diagram = builder.Build()
        stamps: list[int] = []
        clock: list[int] = []
        readers.append(observer.node.create_subscription(
            JointState, "/test_clock/joints", lambda m: stamps.append(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec), 100))
        readers.append(observer.node.create_subscription(
            Clock, "/clock", lambda m: clock.append(m.clock.sec * 10**9 + m.clock.nanosec), 100))
        publisher = sender.clock_publisher()
        wait_for(lambda: matched(publisher, observer.node, "/clock") and matched(joints.publisher, observer.node, "/test_clock/joints"),
                 WAIT_S, "/clock and the joint states to match")
        Simulator(diagram).AdvanceTo(0.05)  # publishes at t = 0, 0.01, …, 0.05
        expected = [k * 10_000_000 for k in range(6)]
        wait_for(lambda: len(stamps) == 6 and len(clock) == 6, WAIT_S, "6 joint states and 6 clock messages")
        assert stamps == clock == expected
    finally:
        for reader in readers:
            observer.node.destroy_subscription(reader)
        sender.close()


# --- RosSubscribe: cached per time, drops with reasons, keeps the last value ---------------------------
def test_a_subscribed_value_is_read_once_per_time(observer):  # noqa: F811
    """Drake caches the port: a message that arrives while the time stays put is seen from the next
    time on (as the module docstring says)."""
    from sotdrake.ros import subscribe as module

    assert "latest at the time it is evaluated" not in module.__doc__
    assert "seen from the next time on" in " ".join(module.__doc__.split())
    subscribe = RosSubscribe("sub_cached", observer)
    port = subscribe.add("vector", "v", "/test_guarantees/cached", default=(0.0, 0.0), size=2)
    sender = RosNode("test_cached_sender")
    try:
        (pub,) = _matched_publishers(sender, observer, (Float64MultiArray, "/test_guarantees/cached"))
        context = subscribe.CreateDefaultContext()
        assert port.Eval(context).tolist() == [0.0, 0.0]
        pub.publish(Float64MultiArray(data=[1.0, 2.0]))
        wait_for(lambda: subscribe.count("v") == 1, WAIT_S, "the message")
        assert port.Eval(context).tolist() == [0.0, 0.0]  # (the same time: the cached value)
        context.SetTime(1e-3)
        assert port.Eval(context).tolist() == [1.0, 2.0]
    finally:
        sender.close()


def _matched_publishers(sender: RosNode, listener: RosNode, *topics: tuple[type, str]) -> list:
    """A publisher of ``sender`` per ``(message type, topic)``, once ``listener``'s subscription to
    each has matched it."""
    publishers = [sender.node.create_publisher(kind, topic, 10) for kind, topic in topics]
    wait_for(lambda: all(matched(pub, listener.node, topic) for pub, (_, topic) in zip(publishers, topics, strict=True)),
             WAIT_S, "the subscriptions")
    return publishers


def _after_each(pub, subscribe, signal, bad, good) -> None:
    """Publish each of ``bad`` then one of ``good``; wait until the good one arrived (one writer:
    in order, so every bad one was handled before)."""
    count = subscribe.count(signal)
    for message in bad:
        pub.publish(message)
    pub.publish(good)
    wait_for(lambda: subscribe.count(signal) == count + 1, WAIT_S, f"the message after {len(bad)} dropped")


def test_dropped_messages_say_why_and_keep_the_last_value(observer, caplog):  # noqa: F811
    from sotdrake.ros import subscribe as module

    assert "the port holds its ``default``" not in module.__doc__.split("A message is")[1]
    assert "keeps the last value" in " ".join(module.__doc__.split())
    subscribe = RosSubscribe("sub_drops", observer)
    joints = subscribe.add("joint_states", "q", "/test_guarantees/joints", names=["a", "b"])
    vector = subscribe.add("vector", "v", "/test_guarantees/vector", size=3)
    sender = RosNode("test_drops_sender")
    try:
        pub_j, pub_v = _matched_publishers(sender, observer, (JointState, "/test_guarantees/joints"),
                                           (Float64MultiArray, "/test_guarantees/vector"))
        with caplog.at_level(logging.WARNING, logger="sotdrake.ros"):
            _after_each(pub_j, subscribe, "q", [], JointState(name=["b", "a"], position=[2.0, 1.0]))
            _after_each(pub_j, subscribe, "q", [JointState(name=["a", "b", "a"], position=[7.0, 8.0, 9.0]),
                                                JointState(name=["a", "b"], position=[float("nan"), 3.0])],
                        JointState(name=["a", "b"], position=[5.0, 6.0]))
            _after_each(pub_v, subscribe, "v", [], Float64MultiArray(data=[1.0, 2.0, 3.0]))
            count = subscribe.count("v")
            for data in ([1.0, 2.0], [1.0, float("inf"), 3.0]):
                pub_v.publish(Float64MultiArray(data=data))
            wait_for(lambda: sum("dropped" in r.getMessage() and "vector" in r.getMessage() for r in caplog.records) == 2,
                     WAIT_S, "both vectors dropped")
        messages = [r.getMessage() for r in caplog.records]
        assert any("naming 'a' more than once" in m for m in messages), messages
        assert any("not all finite: a=nan" in m for m in messages), messages
        assert any("2 values (want 3)" in m for m in messages), messages
        assert any("not all finite: data[1]=inf" in m for m in messages), messages
        assert subscribe.count("v") == count
        context = subscribe.CreateDefaultContext()
        assert joints.Eval(context).tolist() == [5.0, 6.0]
        assert vector.Eval(context).tolist() == [1.0, 2.0, 3.0]  # (the last valid value, not the default)
    finally:
        sender.close()


def test_a_pose_in_another_frame_is_dropped(observer, caplog):  # noqa: F811
    from sotdrake.exceptions import InvalidInput

    subscribe = RosSubscribe("sub_frames", observer)
    world = subscribe.add("pose", "target", "/test_guarantees/pose")
    odom = subscribe.add("pose", "odom", "/test_guarantees/pose_odom", frame="odom")
    with pytest.raises(InvalidInput, match="frame is for a 'pose'"):
        subscribe.add("vector", "v", "/test_guarantees/v", size=1, frame="world")
    with pytest.raises(InvalidInput, match="frame of 'p'"):
        subscribe.add("pose", "p", "/test_guarantees/p", frame="")
    sender = RosNode("test_frames_sender")

    def pose(frame: str, x: float) -> PoseStamped:
        message = PoseStamped()
        message.header.frame_id, message.pose.position.x, message.pose.orientation.w = frame, x, 1.0
        return message

    try:
        pub, pub_odom = _matched_publishers(sender, observer, (PoseStamped, "/test_guarantees/pose"),
                                            (PoseStamped, "/test_guarantees/pose_odom"))
        with caplog.at_level(logging.WARNING, logger="sotdrake.ros"):
            _after_each(pub, subscribe, "target", [], pose("world", 1.0))
            _after_each(pub, subscribe, "target", [pose("map", 2.0), pose("odom", 3.0)], pose("", 4.0))
            _after_each(pub_odom, subscribe, "odom", [pose("world", 5.0)], pose("odom", 6.0))
        messages = [r.getMessage() for r in caplog.records]
        assert any("frame 'map', not 'world'" in m for m in messages), messages
        assert any("frame 'world', not 'odom'" in m for m in messages), messages
        assert subscribe.count("target") == 2 and subscribe.count("odom") == 1
        context = subscribe.CreateDefaultContext()
        assert world.Eval(context)[0] == 4.0 and odom.Eval(context)[0] == 6.0
    finally:
        sender.close()


# --- bags ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("kwargs", "argument"), [
    ({"joint_topic": "relative"}, "joint_topic"),
    ({"points": {"~/x": np.zeros((2, 3))}}, "points"),
    ({"arrays": {"{node}/x": np.zeros(2)}}, "arrays"),
    ({"arrays": {"x": np.zeros(2)}}, "arrays"),
])
def test_a_bag_refuses_relative_topics(tmp_path, kwargs, argument):
    joints = (["a"], np.zeros((2, 1)))
    with pytest.raises(SotError, match=f"write_bag: {argument}: a bag's topic is a fully qualified name"):
        write_bag(tmp_path / "bag", [0.0, 0.1], joints, **kwargs)
    assert list(tmp_path.iterdir()) == []  # (nothing written)


def test_a_trace_bag_holds_matrices_and_booleans_and_names_what_it_leaves_out(tmp_path, caplog):
    t = np.arange(4) * 0.1
    matrices = np.arange(16.0).reshape(4, 2, 2)
    flags = np.array([True, False, True, True])
    trace = {"time": t, "q": np.zeros((4, 2)), "wrench": matrices, "contact": flags,
             "label": np.array(["a", "b", "c", "d"]), "tick_s": np.zeros(3)}
    with caplog.at_level(logging.WARNING, logger="sotdrake.ros"):
        write_trace_bag(tmp_path / "run", trace, (["j0", "j1"], np.array([0, 1])))
    messages = read_bag(tmp_path / "run")
    assert {"/sot/wrench", "/sot/contact"} <= set(messages) and "/sot/label" not in messages
    wrench = [m for _, m in messages["/sot/wrench"]]
    assert [(d.label, d.size, d.stride) for d in wrench[0].layout.dim] == [("rows", 2, 4), ("cols", 2, 2)]
    assert np.array_equal(np.array([m.data for m in wrench]), matrices.reshape(4, 4))
    assert [list(m.data) for _, m in messages["/sot/contact"]] == [[1.0], [0.0], [1.0], [1.0]]
    assert any("'label'" in r.getMessage() and "left out" in r.getMessage() for r in caplog.records)


def test_the_appli_bag_holds_the_target_in_force(tmp_path):
    """A gotoNd over run_command moves the target: the bag's ``/sot/target/rh`` follows it."""
    import sotdrake.ros
    from sotdrake import gotoNd
    from sotdrake.scenarios import talos_appli

    try:
        appli = talos_appli.build_diagram(push_time=None, ros=True)
        simulator = Simulator(appli.diagram)
        simulator.AdvanceTo(0.02)
        moved = np.array([0.4, -0.3, 0.9])
        gotoNd(appli.taskRH, moved, "111", context=simulator.get_mutable_context())
        simulator.AdvanceTo(0.04)
        summary, trace = talos_appli.summarize(appli, simulator, 0.04, 1.0)
        talos_appli.write_bag(appli, tmp_path, summary, trace, every=1)
    finally:
        sotdrake.ros.shutdown()
    messages = read_bag(tmp_path / "run")
    assert "/sot/target_rh" not in messages  # (the target on its own topic only)
    points = messages["/sot/target/rh"]
    assert len(points) == trace["time"].size
    for ns, message in points:
        want = talos_appli.TARGET if ns <= 20_000_000 else moved
        np.testing.assert_allclose([message.point.x, message.point.y, message.point.z], want, atol=1e-12)
