"""A live run: the diagram simulated at real-time rate until stopped, steered by commands.

The loop advances the ``Simulator`` one control tick at a time (``AdvanceTo((k+1)·dt)``, Drake
pacing it at ``realtime_rate``). At each tick boundary it applies the ``attime`` commands that are
due, then the queued commands of the :class:`~.server.CommandServer`, for as long as the run stays
less than ``max_lag`` simulated seconds behind the wall clock (the time the simulator would
otherwise sleep), and beyond that within a credit of ``command_share`` (3 %) of the wall time that
passes: a command that overdraws the credit is paid back over the next ticks, so a flood of
commands slows a run that has no slack by 3 % at most on average, and a run with slack not at all.

The run stops on Ctrl-C (SIGINT), SIGTERM, the ``stop()`` command, after ``duration`` seconds, or
when the simulation raises (a command may be valid and still drive the robot somewhere absurd);
then it writes what the diagram script writes (trace, summary, control graph) and removes its
connection file; :func:`run_live` then raises if the simulation failed.

Figures (``status()``): ``t`` (simulated s), ``wall`` (s since the loop started), ``ticks``,
``lag_ticks`` (ticks the run is behind the wall clock now, ``⌊wall·rate/dt⌋ - ticks``),
``max_lag_ticks`` (the most since the previous ``status()``), the command counts (``withdrawn``:
commands whose client stopped waiting before the run reached them, never applied).
"""

from __future__ import annotations

import contextlib
import heapq
import json
import logging
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, Diagram

from ..exceptions import InvalidInput, SotError, check_number
from ..simulation import frozen_gc
from ..tracing import Tracer, tracers_of
from .arguments import Prepared
from .connection import Connection, default_path, new_token, remove_connection, write_connection
from .server import CommandServer, apply
from .vocabulary import Vocabulary

log = logging.getLogger("sotdrake.live")

#: Most ``attime`` commands waiting at once.
MAX_SCHEDULED = 1000


class DiagramHandles(Protocol):
    """What a script's ``build_diagram`` returns: the built ``diagram``, usually with its ``robot``,
    meta tasks and solver as further fields."""

    @property
    def diagram(self) -> Diagram: ...


@dataclass(order=True)
class _Scheduled:
    time: float
    order: int
    prepared: Prepared = field(compare=False)


class LiveRun:
    """A diagram run live (see the module docstring). ``handles``: what ``build_diagram``
    returned (its meta tasks and solver get their field names in the vocabulary)."""

    def __init__(self, diagram: Diagram, dt: float, handles: object = None, realtime_rate: float = 1.0,
                 port: int = 0, max_lag: float = 0.004, command_share: float = 0.03,
                 meshcat_url: str | None = None):
        dt = check_number("LiveRun: dt (the tick)", dt, 1e-6, 1.0, " s")
        realtime_rate = check_number("LiveRun: realtime_rate", realtime_rate, 1e-3, 1e3)
        max_lag = check_number("LiveRun: max_lag", max_lag, 0.0, 60.0, " s")
        command_share = check_number("LiveRun: command_share", command_share, 0.0, 0.99)
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise InvalidInput(f"LiveRun: port must be an integer in [0, 65535] (0: any free port), got {port!r:.60}")
        self.diagram, self.dt, self.rate, self.max_lag = diagram, float(dt), float(realtime_rate), max_lag
        self.command_share = command_share
        self.simulator = Simulator(diagram)
        self.simulator.set_target_realtime_rate(self.rate)
        self.vocabulary = Vocabulary(diagram, handles)
        self.vocabulary.set_scheduler(self._schedule)
        self.vocabulary.add_function("status", (), lambda c: self.status(), "time, real-time lag, command counts",
                                     query=True)
        self.vocabulary.add_function("stop", (), lambda c: self.stop(), "stop the run (writes its files)")
        self.server = CommandServer(self.vocabulary, new_token(), port=port)
        self.connection = Connection(self.server.host, self.server.port, self.server.token,
                                     os.getpid(), meshcat_url)
        self._stop = threading.Event()
        self._scheduled: list[_Scheduled] = []
        self._order = 0
        self._ticks = 0
        self._wall0 = time.monotonic()
        self._t0 = 0.0
        self._max_lag_ticks = 0
        self._credit = 0.0  # wall seconds commands may still take beyond the slack
        self._last_wall = time.monotonic()
        self.connection_files: list[Path] = []
        self.error: str | None = None  # why the simulation stopped, if it failed
        #: The attime commands refused when their time came (``t``, ``command``, ``answer``).
        self.attime_refused: list[dict] = []

    @property
    def context(self) -> Context:
        return self.simulator.get_mutable_context()

    # --- commands the runner adds ------------------------------------------------------------
    def _schedule(self, at: float, prepared: Prepared) -> str:
        if len(self._scheduled) >= MAX_SCHEDULED:
            raise InvalidInput(f"attime: {MAX_SCHEDULED} commands already scheduled")
        self._order += 1
        heapq.heappush(self._scheduled, _Scheduled(at, self._order, prepared))
        return f"ok: {prepared} at t = {at:.4f} s"

    def status(self) -> str:
        wall = time.monotonic() - self._wall0
        counts = self.server.counts
        report = {
            "t": round(self.context.get_time(), 6),
            "wall": round(wall, 6),
            "ticks": self._ticks,
            "lag_ticks": math.floor(wall * self.rate / self.dt) - self._ticks,
            "max_lag_ticks": self._max_lag_ticks,
            "received": counts.received,
            "accepted": counts.accepted,
            "rejected": counts.rejected,
            "withdrawn": counts.withdrawn,
            "scheduled": len(self._scheduled),
            "attime_refused": len(self.attime_refused),
        }
        self._max_lag_ticks = 0
        return json.dumps(report)

    def stop(self) -> str:
        self._stop.set()
        return "ok: stopping"

    # --- the loop ------------------------------------------------------------------------------
    def write_connection_files(self, *paths: Path | None) -> list[Path]:
        """Write the connection (mode 0600) to ``paths`` and to the per-user default."""
        for path in [*paths, default_path()]:
            if path is not None:
                self.connection_files.append(write_connection(path, self.connection))
        return self.connection_files

    def run(self, duration: float | None = None) -> float:
        """Run until stopped (or ``duration`` s of simulated time); returns the wall time (s)."""
        if duration is not None and not duration > 0:
            raise InvalidInput(f"duration must be > 0 s or None, got {duration!r}")
        previous = {}
        if threading.current_thread() is threading.main_thread():  # signals reach the main thread only
            previous = {s: signal.signal(s, lambda *_: self._stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
        simulator, context = self.simulator, self.context
        tracers = tracers_of(self.diagram)  # streaming ones: their samples go to their files every 100 ticks
        try:
            simulator.Initialize()
            self._t0 = context.get_time()
            end = None if duration is None else self._t0 + duration
            simulator.ResetStatistics()
            self._wall0 = self._last_wall = time.monotonic()
            with frozen_gc():  # the build's objects out of the collections: no full collection in the loop
                self._loop(end, tracers)
        finally:
            for tracer in tracers:  # (the run's end: the files hold the whole run, as simulate's do)
                with contextlib.suppress(OSError, SotError):
                    tracer.flush(context, force=True)
            for s, handler in previous.items():
                signal.signal(s, handler)
            self.server.close()
            for path in self.connection_files:
                remove_connection(path, self.connection)
        return time.monotonic() - self._wall0

    def _loop(self, end: float | None, tracers: list[Tracer]) -> None:
        simulator, context = self.simulator, self.context
        while not self._stop.is_set():
            next_time = self._t0 + (self._ticks + 1) * self.dt
            if end is not None and next_time > end + 1e-9:
                break
            try:
                simulator.AdvanceTo(next_time)
            except (SotError, RuntimeError, ValueError) as error:  # e.g. a command drove q to NaN
                self.error = f"{type(error).__name__}: {error}"
                log.error("live: the simulation stopped at t = %.4f s: %s", context.get_time(), self.error)
                break
            self._ticks += 1
            if self._ticks % 100 == 0:
                try:
                    for tracer in tracers:
                        tracer.flush(context)
                except (OSError, SotError) as error:  # (a full disk, a file deleted): the run stops as on a failed tick
                    self.error = f"the trace could not be written: {error}"
                    log.error("live: the run stopped at t = %.4f s: %s", context.get_time(), self.error)
                    break
            self._boundary(context)

    def _boundary(self, context: Context) -> None:
        self.server.ticked()
        now = context.get_time()
        while self._scheduled and self._scheduled[0].time <= now + 1e-9:
            item = heapq.heappop(self._scheduled)
            ok, text = apply(item.prepared, context)
            (log.info if ok else log.warning)("t = %.3f s: attime %s: %s", now, item.prepared, text)
            if not ok:
                self.attime_refused.append({"t": round(now, 6), "command": str(item.prepared), "answer": text})
        wall = time.monotonic()
        lag = (wall - self._wall0) * self.rate - (now - self._t0)  # simulated seconds behind
        self._max_lag_ticks = max(self._max_lag_ticks, math.floor(lag / self.dt + 1e-9))
        slack = max((self.max_lag - lag) / self.rate, 0.0)  # wall seconds the pacing would sleep
        # Beyond the slack, commands earn command_share of the wall time that passes (kept up to 5 ms).
        self._credit = min(self._credit + self.command_share * (wall - self._last_wall), 0.005)
        self._last_wall = wall
        if slack + self._credit <= 0:
            return
        self.server.process(context, wall + slack + max(self._credit, 0.0), minimum=1)
        self._credit -= max(0.0, time.monotonic() - wall - slack)  # may go negative: paid back later


def open_live(handles: DiagramHandles, out: Path, meshcat=None, port: int = 0,
              realtime_rate: float = 1.0) -> tuple[LiveRun, list[Path]]:
    """The :class:`LiveRun` of ``handles.diagram`` (dt from ``handles.robot.dt``, else 1 ms) and
    its connection files, written in ``out`` (created): what :func:`run_live` and ROS 2's
    ``run_ros`` begin with."""
    robot = getattr(handles, "robot", None)
    dt = robot.dt if robot is not None else 1e-3
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    url = meshcat.web_url() if meshcat is not None else None
    live = LiveRun(handles.diagram, dt, handles, realtime_rate, port, meshcat_url=url)
    return live, live.write_connection_files(out / "live.json")


def close_live(live: LiveRun, handles: DiagramHandles, out: Path, wall: float, summarize: Callable | None = None,
               write: Callable | None = None, label: str = "live", on_stop: Callable | None = None,
               ran: bool = True) -> dict:
    """After ``live`` stopped (``wall`` s of running; ``ran``: False if it never started): the
    summary and trace (``summarize(handles, simulator, duration, wall)``, else the tracer's),
    ``on_stop(out, summary, trace)`` (e.g. a bag), then ``write(out, summary, trace)`` when given
    and the run did not fail, else :func:`~sotdrake.simulation.write_run`. Raises the run's
    failure, after the files are written."""
    from ..simulation import write_run

    simulator = live.simulator
    simulated = simulator.get_context().get_time()
    print(f"sotdrake {label}: stopped at t = {simulated:.3f} s after {wall:.1f} s; writing {out}", file=sys.stderr,
          flush=True)
    summary, trace = None, None
    if not ran:
        summary = {"duration_s": simulated, "wall_s": wall}
    elif summarize is not None:
        try:
            summary, trace = summarize(handles, simulator, simulated, wall)
        except (SotError, RuntimeError, ValueError) as error:
            if live.error is None:
                raise
            log.warning("%s: the script's summary failed after the failure (%s); writing the trace only", label, error)
    if summary is None:
        tracer = getattr(handles, "tracer", None)
        trace = tracer.data(simulator.get_context()) if tracer is not None else None
        summary = {"duration_s": simulated, "wall_s": wall, "realtime_factor": simulated / wall if wall else None}
    summary["live"] = json.loads(live.status())
    summary["live"]["error"] = live.error
    summary["live"]["attime_refused"] = live.attime_refused
    if on_stop is not None and trace is not None:
        on_stop(out, summary, trace)
    if write is not None and trace is not None and live.error is None:
        write(out, summary, trace)
    else:
        write_run(out, handles.diagram, summary, trace)
    if live.error is not None:
        raise SotError(f"the {label} run failed at t = {simulated:.4f} s (files written in {out}): {live.error}")
    return summary


def run_live(handles: DiagramHandles, out: Path, meshcat=None, duration: float | None = None, port: int = 0,
             realtime_rate: float = 1.0, summarize: Callable | None = None,
             write: Callable | None = None) -> dict:
    """Run ``handles.diagram`` live (dt from ``handles.robot.dt``), print how to reach it, and when
    it stops write its files: ``summarize(handles, simulator, duration, wall) -> (summary, trace)``
    and ``write(out, summary, trace)`` when given, else ``write_run`` with the tracer's trace."""
    live, files = open_live(handles, out, meshcat, port, realtime_rate)
    lines = [f"sotdrake live: {handles.diagram.get_name() or 'diagram'} at real-time rate {realtime_rate:g}, "
             "Ctrl-C to stop"]
    if meshcat is not None:
        lines.append(f"  meshcat:  {meshcat.web_url()}")
    lines.append(f"  commands: sotdrake-shell --connection {files[0]}   (127.0.0.1:{live.server.port})")
    print("\n".join(lines), file=sys.stderr, flush=True)
    wall = live.run(duration)
    return close_live(live, handles, Path(out), wall, summarize, write)


def live_meshcat(port: int | None = None):
    """Drake's Meshcat on the loopback only (``localhost``, ``port`` or the first free one from
    7000); its URL is printed once, by :func:`run_live`."""
    from pydrake.geometry import Meshcat, MeshcatParams

    drake_log = logging.getLogger("drake")
    level = drake_log.level
    drake_log.setLevel(logging.WARNING)  # Drake would print the URL too
    try:
        return Meshcat(MeshcatParams(host="localhost", port=port))
    finally:
        drake_log.setLevel(level)


def add_live_arguments(parser) -> None:
    """``--live``, ``--port``, ``--meshcat-port`` and ``--rate`` for a diagram script. With
    ``--live`` the run lasts until stopped unless ``--duration`` is given, so the script's
    ``--duration`` default becomes None: the script applies its own default when not live."""
    group = parser.add_argument_group("live run")
    group.add_argument("--live", action="store_true",
                       help="run at real-time rate until Ctrl-C, steered with sotdrake-shell")
    group.add_argument("--port", type=int, default=0, help="command port on 127.0.0.1 (0: any free port)")
    group.add_argument("--meshcat-port", type=int, default=None, help="Meshcat port (default: from 7000)")
    group.add_argument("--rate", type=float, default=1.0, help="target real-time rate")
    parser.set_defaults(duration=None)
