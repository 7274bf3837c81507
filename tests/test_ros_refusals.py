"""ROS 2 bridge refusals: a mistake is refused when made, with the library's errors, naming the
argument, leaving nothing behind (no system in the builder, no ROS publisher); the node keeps
answering whatever a request or a callback does."""

import json
import os
from types import SimpleNamespace

import pytest

pytest.importorskip("rclpy", reason='ROS 2 is an optional extra: pip install ".[ros2]"')

from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, ZeroOrderHold
from std_msgs.msg import String

from sotdrake.exceptions import InvalidInput, SotError
from sotdrake.ros import (
    RUN_COMMAND_RESPONSE,
    JointCommandPublisher,
    JointStatePublisher,
    RosNode,
    RosPublish,
    RosServices,
    RosSubscribe,
    RunCommandClient,
    TorqueCommandPublisher,
    add_ros_publisher,
)
from tests.test_ros import matched, observer, wait_for  # noqa: F401  (its ROS_DOMAIN_ID and LOCALHOST too)

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::DeprecationWarning:lark")]

WAIT_S = 60.0
DEEP = 600  # nested lists in a request's id


def _ur5():
    from sotdrake.robot import robot

    builder = DiagramBuilder()
    return builder, robot(builder, "ur5")


def _names(builder: DiagramBuilder) -> list[str]:
    return sorted(system.get_name() for system in builder.GetSystems())


# --- the node's name is checked before rclpy is touched ---------------------------------------------
@pytest.mark.parametrize("name", [3, None, "", "noeud_é", "n²", "1abc", "a-b", "n" * 256])
def test_a_bad_node_name_is_refused_before_rclpy(name):
    with pytest.raises(InvalidInput, match="node name"):
        RosNode(name)


# --- a callback's exception does not stop the node ------------------------------------------------
def test_the_executor_survives_a_callback_that_raises():
    node = RosNode(f"test_refusals_spin_{os.getpid()}")
    try:
        received: list[str] = []

        def callback(message: String) -> None:
            if message.data == "boom":
                raise RuntimeError("a callback that fails")
            received.append(message.data)

        node.node.create_subscription(String, "/test_refusals/spin", callback, 10)
        publisher = node.node.create_publisher(String, "/test_refusals/spin", 10)
        wait_for(lambda: publisher.get_subscription_count() > 0, WAIT_S, "the subscription")
        publisher.publish(String(data="boom"))
        tries = [0]

        def later() -> bool:  # (published again every 0.5 s until one arrives)
            tries[0] += 1
            if tries[0] % 25 == 1:
                publisher.publish(String(data="after"))
            return "after" in received

        wait_for(later, WAIT_S, "a message after the callback that raised")
        assert node._thread.is_alive()
    finally:
        node.close()


# --- run_command: an id that is not a JSON scalar is answered, never raised ------------------------
class _Server:
    def __init__(self):
        self.lines: list[bytes] = []

    def _handle_line(self, client, number, line) -> None:
        self.lines.append(line)


class _Live:
    def __init__(self):
        self.server = _Server()
        self.vocabulary = SimpleNamespace(add_function=lambda *args, **kwargs: None)


@pytest.fixture()
def services(observer):  # noqa: F811
    answers: list[dict] = []
    subscription = observer.node.create_subscription(String, RUN_COMMAND_RESPONSE,
                                                     lambda m: answers.append(json.loads(m.data)), 100)
    services = RosServices(_Live(), observer, hold=False)  # type: ignore[arg-type]
    wait_for(lambda: matched(services.responses, observer.node, RUN_COMMAND_RESPONSE), WAIT_S, "the response subscription")
    yield services, answers
    observer.node.destroy_subscription(subscription)
    services.close(flush_s=1.0)


@pytest.mark.parametrize("request_text", [
    '{"id": ' + "[" * DEEP + "]" * DEEP + ', "command": "time()"}',
    '{"id": ' + "[" * DEEP + "]" * DEEP + "}",
    '{"id": {"a": [1]}, "command": "time()"}',
    '{"id": "' + "x" * 5000 + '", "command": "time()"}',
])
def test_a_request_id_that_is_not_a_json_scalar_is_refused_with_an_answer(services, request_text):
    services, answers = services
    services._request(String(data=request_text))
    wait_for(lambda: answers, WAIT_S, "the answer")
    assert answers[0]["ok"] is False and answers[0]["id"] is None and "'id'" in answers[0]["error"]
    assert services.live.server.lines == []  # not forwarded to the run


def test_a_scalar_request_id_is_forwarded(services):
    services, answers = services
    services._request(String(data='{"id": "a-1", "command": "time()"}'))
    assert services.live.server.lines == [b"time()"]


def test_an_answer_too_deep_to_write_goes_out_as_an_error(services):
    services, answers = services
    deep: list = []
    for _ in range(5000):
        deep = [deep]
    services.respond({"id": deep, "ok": True, "answer": "0"})  # (from the simulation thread: must not raise)
    wait_for(lambda: answers, WAIT_S, "the answer")
    assert answers[0] == {"id": None, "ok": False, "error": answers[0]["error"]} and "JSON" in answers[0]["error"]


# --- the client's node is not the run's -----------------------------------------------------------
def test_the_client_has_a_node_name_of_its_own():
    client = RunCommandClient(timeout=1.0)
    try:
        assert client.ros.name != "sotdrake" and client.ros.name.startswith("sotdrake_client")
        assert str(os.getpid()) in client.ros.name
    finally:
        client.close()
        client.ros.close()


# --- add_ros_publisher: all or nothing --------------------------------------------------------------
@pytest.mark.parametrize(("kwargs", "says"), [
    ({"topic": "{bad}"}, "topic"),
    ({"topic": "/test_refusals/state_a", "joint_states": "{bad}"}, "topic"),
    ({"topic": "/test_refusals/state_b", "joint_states": "/rosout"}, "ROS refused|carries rcl_interfaces/msg/Log"),
    ({"topic": "/test_refusals/same", "joint_states": "/test_refusals/same"}, "two topics"),
])
def test_add_ros_publisher_refused_by_ros_leaves_the_builder_unchanged(observer, kwargs, says):  # noqa: F811
    builder, robot = _ur5()
    before = _names(builder)
    with pytest.raises(InvalidInput, match=says):
        add_ros_publisher(robot, node=observer, **kwargs)
    assert _names(builder) == before
    assert kwargs["topic"] == "{bad}" or observer.node.count_publishers(kwargs["topic"]) == 0  # (none left)
    added = add_ros_publisher(robot, topic="/test_refusals/state_ok", joint_states="/test_refusals/joints_ok",
                              node=observer)  # (the names are still free)
    assert added.joint_states is not None


# --- command publishers: ROS's refusals as InvalidInput naming the argument ---------------------------
def test_command_publishers_refuse_topics_and_gains_with_invalid_input(observer):  # noqa: F811
    _, robot = _ur5()
    plant = robot.model.plant
    for topic in ("{bad}", "/rosout"):
        with pytest.raises(InvalidInput, match="topic"):
            JointStatePublisher(plant, topic, node=observer)
    with pytest.raises(InvalidInput, match="topic"):
        JointCommandPublisher(plant, "{bad}", node=observer)
    na = plant.num_actuators()
    for kp in (["a"] * na, "5", True, [1.0] * (na + 1), -1.0):
        with pytest.raises(InvalidInput, match="kp"):
            TorqueCommandPublisher(plant, kp=kp, kd=1.0, node=observer)
    with pytest.raises(InvalidInput, match="prefix"):
        TorqueCommandPublisher(plant, kp=1.0, kd=1.0, prefix="{bad}", node=observer)


# --- after Build(): refused ---------------------------------------------------------------------------
def test_ros_publish_add_after_build_is_refused(observer):  # noqa: F811
    builder = DiagramBuilder()
    publish = builder.AddSystem(RosPublish("test_refusals_built_pub", observer))
    source = builder.AddSystem(ConstantVectorSource([1.0]))
    builder.Connect(source.get_output_port(), publish.add("double", "x", "/test_refusals/built_x"))
    builder.Build()
    with pytest.raises(SotError, match="already built"):
        publish.add("double", "late", "/test_refusals/built_late")
    assert list(publish.signals) == ["x"] and observer.node.count_publishers("/test_refusals/built_late") == 0


def test_ros_subscribe_add_after_build_is_refused(observer):  # noqa: F811
    builder = DiagramBuilder()
    subscribe = builder.AddSystem(RosSubscribe("test_refusals_built_sub", observer))
    hold = builder.AddSystem(ZeroOrderHold(0.1, 1))
    builder.Connect(subscribe.add("double", "x", "/test_refusals/built_sx"), hold.get_input_port())
    builder.Build()
    with pytest.raises(SotError, match="already built"):
        subscribe.add("double", "late", "/test_refusals/built_slate")
    assert list(subscribe.slots) == ["x"]


# --- sizes are bounded; a refused add leaves no ROS publisher -------------------------------------
@pytest.mark.parametrize(("kind", "kwargs", "topic"), [
    ("vector", {"size": 2**63}, "/test_refusals/size_a"),
    ("vector", {"size": 10**12}, "/test_refusals/size_b"),
    ("matrix", {"shape": (10**7, 10**7)}, "/test_refusals/size_c"),
])
def test_ros_publish_bounds_sizes_and_leaks_no_publisher(observer, kind, kwargs, topic):  # noqa: F811
    publish = RosPublish("test_refusals_sizes", observer)
    with pytest.raises(InvalidInput, match="100000"):
        publish.add(kind, "s", topic, **kwargs)
    assert publish.signals == {} and publish.num_input_ports() == 0
    assert observer.node.count_publishers(topic) == 0
    publish.add("double", "s", topic)  # (same name, another type: nothing left in the way)


def test_ros_subscribe_bounds_sizes(observer):  # noqa: F811
    subscribe = RosSubscribe("test_refusals_sub_sizes", observer)
    with pytest.raises(InvalidInput, match="100000"):
        subscribe.add("vector", "v", "/test_refusals/sub_size", size=2**40)
    assert subscribe.slots == {} and subscribe.num_output_ports() == 0


# --- simulating with a node that is shut down ----------------------------------------------------------
def test_simulating_after_the_node_is_closed_names_the_system():
    node = RosNode(f"test_refusals_closed_{os.getpid()}")
    builder = DiagramBuilder()
    publish = builder.AddSystem(RosPublish("test_refusals_closed_pub", node))
    source = builder.AddSystem(ConstantVectorSource([1.0]))
    builder.Connect(source.get_output_port(), publish.add("double", "x", "/test_refusals/closed"))
    publish.trigger(1, 1e-3)
    diagram = builder.Build()
    node.close()
    with pytest.raises(SotError, match=r"test_refusals_closed_pub.*shut down"):
        Simulator(diagram).AdvanceTo(0.01)


# --- names, counts and message types ------------------------------------------------------------------
def test_numpy_counts_are_taken_and_bools_refused(observer):  # noqa: F811
    import numpy as np

    publish = RosPublish("test_refusals_np_pub", observer, depth=np.int64(5))
    publish.add("vector", "v", "/test_refusals/np_v", size=np.int64(3))
    publish.add("matrix", "m", "/test_refusals/np_m", shape=(np.int32(2), np.int64(3)))
    assert [publish.get_input_port(i).size() for i in range(2)] == [3, 6]
    assert publish.trigger(np.int64(2), np.float64(1e-3)) == pytest.approx(2e-3)
    subscribe = RosSubscribe("test_refusals_np_sub", observer, depth=np.int64(3))
    assert subscribe.add("vector", "v", "/test_refusals/np_sv", size=np.int64(4)).size() == 4
    for system in (RosPublish, RosSubscribe):
        with pytest.raises(InvalidInput, match="depth"):
            system("test_refusals_bool_depth", observer, depth=True)


@pytest.mark.parametrize("system", [RosPublish, RosSubscribe])
def test_a_system_without_a_name_is_refused(observer, system):  # noqa: F811
    with pytest.raises(InvalidInput, match="name"):
        system(None, observer)


def test_a_second_node_of_one_name_is_refused_until_the_first_is_closed():
    name = f"test_refusals_twice_{os.getpid()}"
    first = RosNode(name)
    try:
        with pytest.raises(InvalidInput, match="already open"):
            RosNode(name)
    finally:
        first.close()
    RosNode(name).close()


@pytest.mark.parametrize("joints", [[], ["shoulder_pan_joint", "shoulder_pan_joint"], "shoulder_pan_joint", [3]])
def test_joint_command_publisher_refuses_empty_repeated_or_odd_joints(observer, joints):  # noqa: F811
    _, robot = _ur5()
    with pytest.raises(InvalidInput, match="joints"):
        JointCommandPublisher(robot.model.plant, "/test_refusals/joint_commands", joints=joints, node=observer)
    assert observer.node.count_publishers("/test_refusals/joint_commands") == 0


def test_a_topic_of_another_message_type_is_refused(observer):  # noqa: F811
    observer.node.create_publisher(String, "/test_refusals/typed", 10)
    subscribe = RosSubscribe("test_refusals_typed_sub", observer)
    with pytest.raises(InvalidInput, match="std_msgs/msg/String"):
        subscribe.add("double", "x", "/test_refusals/typed")
    assert subscribe.slots == {} and subscribe.num_output_ports() == 0
    publish = RosPublish("test_refusals_typed_pub", observer)
    with pytest.raises(InvalidInput, match="std_msgs/msg/String"):
        publish.add("vector", "x", "/test_refusals/typed", size=2)
    assert publish.signals == {} and observer.node.count_publishers("/test_refusals/typed") == 1
