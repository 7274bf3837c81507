"""The other side of :mod:`.services`, for a script in another process (``diagrams/ros_test.py``)."""

from __future__ import annotations

import json
import os
import threading
import time

from std_msgs.msg import String
from std_srvs.srv import Empty

from ..exceptions import SotError, check_number, check_type
from .node import RosNode, ros_node
from .services import REQUEST_QOS, RUN_COMMAND_REQUEST, RUN_COMMAND_RESPONSE, START_SERVICE

#: The handshake's request: a query every run answers, which changes nothing.
HELLO = "time()"
#: How often (s) the handshake's request is sent again until it is answered.
RESEND_S = 0.5
#: The longest time-out (s) a client takes.
MAX_TIMEOUT_S = 1e6


def _check_timeout(timeout: object) -> float:
    """``timeout`` as a float if it is a number of seconds in [0, :data:`MAX_TIMEOUT_S`], else :class:`InvalidInput`."""
    return check_number("timeout", timeout, 0.0, MAX_TIMEOUT_S, " s")


class RunCommandClient:
    """``command(line)`` sends one ``run_command`` and waits for its answer (a dict with ``ok`` and
    ``answer`` or ``error``); ``start()`` calls ``start_dynamic_graph``.

    Without ``node``, the client has a node of its own, ``sotdrake_client_<pid>`` (the run's is
    ``sotdrake``: two nodes of one name confuse ROS tools), closed by ``sotdrake.ros.shutdown()``.
    ``timeout`` (s, 0 to :data:`MAX_TIMEOUT_S`) is how long each call waits unless given its own.
    A bad argument is :class:`~sotdrake.exceptions.InvalidInput`, a call on a closed client or node
    :class:`~sotdrake.exceptions.SotError`, before anything is sent."""

    def __init__(self, node: RosNode | None = None, timeout: float = 120.0):
        timeout = _check_timeout(timeout)
        if node is not None:
            check_type("node", node, RosNode, "a sotdrake.ros.RosNode or None").check_open("RunCommandClient")
        self.ros, self.timeout = node or ros_node(f"sotdrake_client_{os.getpid()}"), timeout
        node_ = self.ros.node
        self._answers: dict[str, dict] = {}
        self._pending: set[str] = set()
        self._arrived = threading.Condition()
        self._count = 0
        self._prefix = f"{node_.get_name()}-{os.getpid()}-{id(self):x}"
        # (KEEP_ALL both ways: a request the run cannot take yet holds publish() back, or makes it
        # raise, never overwrites an earlier one; no answer is dropped before it is read)
        self.requests = node_.create_publisher(String, RUN_COMMAND_REQUEST, REQUEST_QOS)
        self.responses = node_.create_subscription(String, RUN_COMMAND_RESPONSE, self._response, REQUEST_QOS)
        self.starter = node_.create_client(Empty, START_SERVICE)
        self.closed = False
        self.ros.context.on_shutdown(self._node_shut_down)  # (kept weakly by the context)

    def _node_shut_down(self) -> None:
        """Wake a :meth:`wait`, :meth:`command` or :meth:`start` under way: the node is shut down.
        The context calls this holding its own lock, which :meth:`_usable` takes: a thread of its
        own notifies, so that a waiting call that holds ``_arrived`` never waits on that lock."""
        try:
            threading.Thread(target=self._notify, name="sotdrake-client-wake", daemon=True).start()
        except RuntimeError:  # (the interpreter is exiting: no call is waiting)
            pass

    def _notify(self) -> None:
        with self._arrived:
            self._arrived.notify_all()

    def _usable(self) -> bool:
        """Neither this client nor its node is closed."""
        return not self.closed and self.ros.is_open()

    def _check_usable(self, what: str) -> None:
        """:class:`SotError` if this client or its node is closed."""
        if not self._usable():
            raise SotError(f"RunCommandClient.{what}: the client is closed"
                           + ("" if self.closed else f" (its ROS node {self.ros.name} is shut down)"))

    def _response(self, message: String) -> None:
        try:
            answer = json.loads(message.data)
        except (ValueError, RecursionError):  # (not an answer: JSON nested too deeply, bad text)
            return
        if isinstance(answer, dict) and isinstance(answer.get("id"), str):
            with self._arrived:
                if answer["id"] in self._pending:
                    self._pending.discard(answer["id"])
                    self._answers[answer["id"]] = answer
                    self._arrived.notify_all()

    def ready(self) -> bool:
        """Both services are up and matched with this client, now (False once it is closed)."""
        return (self._usable() and self.requests.get_subscription_count() > 0
                and self.responses.get_publisher_count() > 0 and self.starter.service_is_ready())

    def wait(self, timeout: float | None = None) -> None:
        """Wait for both services (the seed's ``wait_for_service``), up to ``timeout`` s, then for
        one answer to :data:`HELLO` (a round trip: :meth:`ready` is the check that does not wait).

        Each side of a topic discovers the other on its own: a publisher matched here may not yet be
        matched in the run, whose reader then drops what it was sent (volatile QoS), and so may its
        answer. The handshake sends :data:`HELLO` again every :data:`RESEND_S` s until an answer
        comes back; from then on, both topics deliver every message (reliable QoS). Each request
        the handshake sends is a command the run counts."""
        wait = self.timeout if timeout is None else _check_timeout(timeout)
        self._check_usable("wait")
        deadline = time.monotonic() + wait
        while not self.ready():
            self._check_usable("wait")
            if time.monotonic() > deadline:
                raise SotError(f"run_command ({RUN_COMMAND_REQUEST}) and {START_SERVICE} not available after "
                               f"{wait:g} s (same ROS_DOMAIN_ID?)")
            time.sleep(0.05)
        sent: set[str] = set()
        with self._arrived:
            try:
                while True:
                    sent.add(self._send(HELLO))
                    left = deadline - time.monotonic()
                    if self._arrived.wait_for(lambda: self._ended(sent), max(0.0, min(RESEND_S, left))):
                        self._check_usable("wait")
                        return
                    if left <= RESEND_S:
                        raise SotError(f"run_command ({RUN_COMMAND_REQUEST}): no answer to {HELLO!r} within {wait:g} s")
            finally:
                self._forget(sent)

    def _ended(self, idents: set[str]) -> bool:
        """An answer to one of ``idents`` arrived, or the client or its node was closed."""
        return not self._usable() or any(ident in idents for ident in self._answers)

    def _send(self, line: str) -> str:
        """Publish ``line`` as a request (the caller holds ``_arrived``); its id."""
        self._count += 1
        ident = f"{self._prefix}-{self._count}"
        self._pending.add(ident)
        try:
            self.requests.publish(String(data=json.dumps({"id": ident, "command": line})))
        except Exception as error:  # (the node shut down under the call)
            self._check_usable("send")
            raise SotError(f"run_command: the request could not be sent: {error}") from error
        return ident

    def _forget(self, idents: set[str]) -> None:
        """Drop ``idents`` (the caller holds ``_arrived``): an answer to one of them that comes late is dropped too."""
        for ident in idents:
            self._pending.discard(ident)
            self._answers.pop(ident, None)

    def command(self, line: str, timeout: float | None = None) -> dict:
        """Send ``line``; its answer (raises :class:`SotError` when none comes within ``timeout`` s,
        or when the client is closed meanwhile)."""
        line = str.__str__(check_type("run_command: line", line, str, "a command line (str)"))
        wait = self.timeout if timeout is None else _check_timeout(timeout)
        self._check_usable("command")
        with self._arrived:
            ident = self._send(line)
            try:
                if not self._arrived.wait_for(lambda: self._ended({ident}), wait):
                    raise SotError(f"run_command {line!r:.100}: no answer within {wait:g} s")
                self._check_usable("command")
                return self._answers.pop(ident)
            finally:
                self._forget({ident})

    def start(self, timeout: float | None = None) -> None:
        """Call ``start_dynamic_graph`` and wait for its reply (raises :class:`SotError` when none
        comes within ``timeout`` s, or when the client is closed meanwhile)."""
        wait = self.timeout if timeout is None else _check_timeout(timeout)
        self._check_usable("start")
        with self._arrived:
            future = self.starter.call_async(Empty.Request())
            future.add_done_callback(lambda _: self._notify())
            if not self._arrived.wait_for(lambda: future.done() or not self._usable(), wait):
                raise SotError(f"{START_SERVICE}: no reply within {wait:g} s")
            self._check_usable("start")

    def close(self) -> None:
        """Destroy this client's publisher, subscription and service client (again: nothing); a
        :meth:`wait`, :meth:`command` or :meth:`start` under way in another thread raises
        :class:`SotError`, as it does when the client's node is shut down."""
        with self._arrived:
            if self.closed:
                return
            self.closed = True
            self._arrived.notify_all()
        if not self.ros.is_open():  # (they went with the node)
            return
        node = self.ros.node
        node.destroy_publisher(self.requests)
        node.destroy_subscription(self.responses)
        node.destroy_client(self.starter)


def wait_for_services(timeout: float = 120.0, node: RosNode | None = None) -> RunCommandClient:
    """A :class:`RunCommandClient` once both services are available (``timeout`` s at most)."""
    client = RunCommandClient(node, timeout)
    client.wait(timeout)
    return client
