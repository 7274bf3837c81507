"""``run_command`` and ``start_dynamic_graph`` on a live run, as on the robot.

* ``start_dynamic_graph`` (``std_srvs/Empty``): the graph holds still (simulated time stays at 0,
  nothing is published) until it is called, as the SoT's device on the robot.
* ``run_command``: one command line of the live channel's grammar
  (:func:`~sotdrake.live.grammar.parse_command`) checked against its allow-list
  (:class:`~sotdrake.live.vocabulary.Vocabulary`) and applied at a tick boundary, never evaluated.
  The seed's ``dynamic_graph_bridge_msgs/RunCommand`` has no wheel and a custom service type needs
  a ROS build, so a request is a ``std_msgs/String`` on :data:`RUN_COMMAND_REQUEST` holding the JSON
  ``{"id": "<any text>", "command": "sot.push('taskrh')"}`` (or just the command line) and its
  answer a ``std_msgs/String`` on :data:`RUN_COMMAND_RESPONSE` holding
  ``{"id": …, "ok": true, "answer": "…"}`` or ``{"id": …, "ok": false, "error": "…"}``.

Commands go through the live run's own queue (:class:`~sotdrake.live.server.CommandServer`), so
they cost the simulation what a TCP command costs, and the TCP channel stays open beside them.

No request is dropped by the run: the request reader keeps every message (reliable, ``KEEP_ALL``:
:data:`REQUEST_QOS`). While the command queue is full, a request waits for room (up to the
server's ``busy_timeout``, then it is answered ``ok: false``, ``busy: … rejected``); meanwhile the
reader stops acknowledging, and a reliable writer holds its requests back: a ``KEEP_ALL`` writer
(:class:`~.client.RunCommandClient`'s) blocks in ``publish`` and at worst raises there, a
``KEEP_LAST`` writer of depth N may overwrite its own oldest unacknowledged requests once N wait.
So every request the run receives is answered, and every request a ``KEEP_ALL`` writer published
without an error is received.

``status()`` says whether the graph is held: ``"held": true`` until ``start_dynamic_graph``, with
``wall``, ``lag_ticks`` and ``max_lag_ticks`` 0 (the run's clock starts with its loop: a held graph
is not behind); ``"held": false`` and the live run's figures from then on.
"""

from __future__ import annotations

import json
import logging
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.duration import Duration
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from std_srvs.srv import Empty

from ..live.connection import remove_connection
from ..live.runner import DiagramHandles, LiveRun, close_live, open_live
from ..simulation import json_safe
from .node import RosNode, ros_node

log = logging.getLogger("sotdrake.ros")

RUN_COMMAND_REQUEST = "/run_command/request"
RUN_COMMAND_RESPONSE = "/run_command/response"
START_SERVICE = "/start_dynamic_graph"
#: Queue depth of the command topics (reliable QoS): the answers a slow reader may lag behind by.
DEPTH = 1000
#: The QoS of the request reader, and of :class:`~.client.RunCommandClient`'s request writer and
#: answer reader: reliable, every message kept until it is taken (a full reader holds the writer
#: back, never drops a message).
REQUEST_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
#: The longest string a request's ``id`` may be.
MAX_ID_CHARS = 1000


def _is_id(ident: object) -> bool:
    return ident is None or isinstance(ident, (bool, int, float)) or (isinstance(ident, str) and len(ident) <= MAX_ID_CHARS)


def check_id(ident: object) -> object:
    """``ident`` if it is a request id: a JSON scalar (a string of at most :data:`MAX_ID_CHARS`
    characters, a number, true, false or null), else :class:`ValueError` saying so."""
    if _is_id(ident):
        return ident
    raise ValueError(f"'id' must be a JSON string (at most {MAX_ID_CHARS} characters), number or null, "
                     f"got a {'string too long' if isinstance(ident, str) else type(ident).__name__}")


class _Answers:
    """Stands for a TCP client in the live server's queue: answers go to the response topic."""

    def __init__(self, services: RosServices):
        self.services = services
        self.ids: dict[int, object] = {}
        self.lock = threading.Lock()

    def queued(self) -> None:
        pass

    def send(self, data: bytes, queued: bool = False) -> None:
        answer = json.loads(data)
        with self.lock:
            answer["id"] = self.ids.pop(answer["id"], answer["id"])
        self.services.respond(answer)


class RosServices:
    """``run_command`` and ``start_dynamic_graph`` for ``live`` (see the module docstring)."""

    def __init__(self, live: LiveRun, node: RosNode | None = None, hold: bool = True):
        self.live, self.ros = live, node or ros_node()
        self.started = threading.Event()
        self.held = hold  # (until wait_for_start returns: the run loop has not begun)
        if not hold:
            self.started.set()
        self._answers = _Answers(self)
        self._count = 0
        node_ = self.ros.node
        self.responses = node_.create_publisher(String, RUN_COMMAND_RESPONSE, DEPTH)
        self.requests = node_.create_subscription(String, RUN_COMMAND_REQUEST, self._request, REQUEST_QOS)
        # (a group of its own: the service answers while a request waits for room in the queue)
        self.service = node_.create_service(Empty, START_SERVICE, self._start,
                                            callback_group=MutuallyExclusiveCallbackGroup())
        live.vocabulary.add_function("status", (), lambda c: self.status(), "time, real-time lag, command counts, "
                                     "held (before start_dynamic_graph)", query=True)

    def status(self) -> str:
        """The live run's ``status()`` with ``held``: while the graph is held (before
        :meth:`wait_for_start` returns), ``wall``, ``lag_ticks`` and ``max_lag_ticks`` are 0 (the
        run's clock starts with its loop: a held graph is not behind)."""
        report = json.loads(self.live.status())
        if self.held:
            report.update(wall=0.0, lag_ticks=0, max_lag_ticks=0)
        report["held"] = self.held
        return json.dumps(report)

    def _start(self, request, response):
        if not self.started.is_set():
            log.info("start_dynamic_graph: the graph starts")
        self.started.set()
        return response

    def _request(self, message: String) -> None:
        """One request: refused with an answer (``ok`` false), never an exception: not JSON with a
        ``command`` string, not UTF-8, an ``id`` that is not a JSON scalar (:func:`check_id`; answered
        to a null id)."""
        text, ident = message.data, None
        try:
            if text.lstrip().startswith("{"):
                request = json.loads(text)
                ident = request.get("id")  # (first: a refused command is still answered to its id)
                ident = check_id(ident)  # (a list or object is not one: answered to null)
                text = request["command"]
                if not isinstance(text, str):
                    raise TypeError("command is not a string")
            line = text.encode("utf-8")
        except (ValueError, KeyError, TypeError, AttributeError, RecursionError) as error:
            if not _is_id(ident):
                ident = None
            # (RecursionError: JSON nested too deeply; UnicodeEncodeError, a ValueError: a lone surrogate)
            self.respond({"id": ident, "ok": False, "error": f"bad request (JSON with 'command', UTF-8 text): {error!s:.200}"})
            return
        with self._answers.lock:
            self._count += 1
            self._answers.ids[self._count] = ident
        self.live.server._handle_line(self._answers, self._count, line)  # type: ignore[arg-type]

    def respond(self, answer: dict) -> None:
        """Publish ``answer`` as JSON (an id of NaN: null, JSON has no NaN); an answer that cannot be
        written (nested too deeply) goes out as an error to a null id, never an exception."""
        try:
            text = json.dumps(json_safe(answer))
        except (RecursionError, ValueError, TypeError) as error:
            text = json.dumps({"id": None, "ok": False, "error": f"an answer could not be written as JSON: {error!s:.200}"})
        self.responses.publish(String(data=text))

    def wait_for_start(self, poll: float = 0.01) -> bool:
        """Apply commands (at t = 0) until ``start_dynamic_graph`` is called (True) or the run is
        stopped (``stop()``, Ctrl-C: False)."""
        try:
            while not self.started.wait(poll):
                self.live.server.process(self.live.context, time.monotonic() + poll, minimum=0)
                if self.live._stop.is_set():
                    return False
        except KeyboardInterrupt:
            return False
        self.held = False
        return True

    def close(self, flush_s: float = 10.0) -> None:
        """Stop answering. The last answers (``stop()``'s among them) are delivered first: the
        response publisher waits, up to ``flush_s`` s, until every subscriber has acknowledged them
        (reliable QoS), or a loaded host could lose them with the publisher."""
        node = self.ros.node
        if not self.responses.wait_for_all_acked(Duration(seconds=flush_s)):
            log.warning("run_command: some answers were not acknowledged within %g s", flush_s)
        node.destroy_subscription(self.requests)
        node.destroy_publisher(self.responses)
        node.destroy_service(self.service)


def run_ros(handles: DiagramHandles, out: Path, meshcat=None, duration: float | None = None, port: int = 0,
            realtime_rate: float = 1.0, summarize: Callable | None = None, write: Callable | None = None,
            hold: bool = True, on_stop: Callable | None = None) -> dict:
    """:func:`~sotdrake.live.run_live` with the ROS 2 services: waits for ``start_dynamic_graph``
    (``hold``), runs until stopped, then ``summarize``, ``on_stop(out, summary, trace)`` (e.g. a
    bag) and ``write`` as ``run_live``."""
    live, files = open_live(handles, out, meshcat, port, realtime_rate)
    services = RosServices(live, hold=hold)
    print(f"sotdrake ros: {handles.diagram.get_name() or 'diagram'}: services {START_SERVICE}, run_command on "
          f"{RUN_COMMAND_REQUEST} -> {RUN_COMMAND_RESPONSE}; commands also by sotdrake-shell --connection "
          f"{files[0]}", file=sys.stderr, flush=True)
    if hold:
        print("sotdrake ros: waiting for start_dynamic_graph", file=sys.stderr, flush=True)
    started = services.wait_for_start()
    wall = live.run(duration) if started else 0.0
    services.close()
    if not started:  # run() never began: close what it would have closed
        live.server.close()
        for path in live.connection_files:
            remove_connection(path, live.connection)
    ran = started and live.simulator.get_context().get_time() > 0
    return close_live(live, handles, Path(out), wall, summarize, write, label="ros", on_stop=on_stop, ran=ran)
