"""The command server inside a live run: TCP on 127.0.0.1, a token, a bounded queue.

Threads: one accepts connections (at most ``max_connections`` at a time); each connection has a
reader and a writer. The reader checks the token (first line, within ``auth_timeout`` s), then cuts
the stream into lines (at most 64 KiB: a longer one is answered at once and skipped) and puts them
in one bounded queue (``queue_size``); when the queue is full the reader waits, so a flooding client
is slowed down by TCP itself, and after ``busy_timeout`` s answers ``busy``. The writer sends the
answers; a client that does not read them is dropped once ``max_unsent`` are waiting.

The simulation thread calls :meth:`CommandServer.process` at tick boundaries: for each queued line,
in arrival order, until its deadline (at least ``minimum`` per call), it parses the line
(:func:`~.grammar.parse_command`), checks it against the allow-list
(:meth:`~.vocabulary.Vocabulary.prepare`) and applies it to the context, and answers ``ok`` (or the
value asked for) or why it was refused: the grammar's, the allow-list's or the API's error. All the
work a command costs is thus done within the time the runner grants it.

A client that stops waiting for an answer sends ``#withdraw <id>`` (see :mod:`.framing`): the
reader answers it at once, without the simulation thread. A command still waiting in the queue is
then never applied: it is answered ``{"ok": false, "withdrawn": true, "error": "<why it waited>;
..."}`` and counted in ``withdrawn``; one the simulation thread has begun to apply gets its usual
answer. Either way the client learns the truth, even when the run does not tick (numba compiling
before the first tick, a held or stopped run).
"""

from __future__ import annotations

import hmac
import logging
import queue
import socket
import threading
import time
from dataclasses import dataclass

from pydrake.systems.framework import Context

from ..exceptions import SotError
from .arguments import Prepared
from .connection import HOST
from .framing import MAX_LINE, WITHDRAW, LineReader, LineTooLong, answer
from .grammar import parse_command
from .vocabulary import Vocabulary

log = logging.getLogger("sotdrake.live")


@dataclass
class ServerCounts:
    """Counts since the start: lines received, answered ok, rejected (grammar, allow-list, API,
    busy, too long), withdrawn by their client before the run reached them (never applied)."""

    received: int = 0
    accepted: int = 0
    rejected: int = 0
    withdrawn: int = 0


@dataclass(eq=False)
class _Request:
    """A queued line; ``state`` (under the server's lock): ``queued``, then ``taken`` by the
    simulation thread or ``withdrawn`` by its client, whichever comes first."""

    client: _Client
    ident: int
    line: bytes
    state: str = "queued"


class _Client:
    """One connection: a reader thread, a writer thread and the answers waiting to be sent."""

    def __init__(self, server: CommandServer, sock: socket.socket, address):
        self.server, self.sock, self.address = server, sock, address
        self.outgoing: queue.Queue[bytes | None] = queue.Queue(maxsize=server.max_unsent)
        self.closed = threading.Event()
        self._lock = threading.Lock()
        self._in_flight = 0  # commands queued for the simulation, not answered yet
        self._reading = True
        self.writer: threading.Thread | None = None

    def send(self, data: bytes, queued: bool = False) -> None:
        """Queue an answer (``queued``: the answer to a command that was in the simulation queue)."""
        with self._lock:
            if queued:
                self._in_flight -= 1
            last = not self._reading and self._in_flight == 0
        if self.closed.is_set():
            return
        try:
            self.outgoing.put_nowait(data)
            if last:
                self.outgoing.put_nowait(None)
        except queue.Full:
            log.warning("live: dropping client %s: %d answers unread", self.address, self.server.max_unsent)
            self.close()

    def queued(self) -> None:
        with self._lock:
            self._in_flight += 1

    def finish(self) -> None:
        """The peer sent its last line: close once every answer is sent."""
        with self._lock:
            self._reading = False
            last = self._in_flight == 0
        if last:
            try:
                self.outgoing.put_nowait(None)
            except queue.Full:
                self.close()

    def close(self) -> None:
        """Drop the connection now."""
        if not self.closed.is_set():
            self.closed.set()
            try:
                self.sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            try:
                self.outgoing.put_nowait(None)
            except queue.Full:
                pass

    def write_loop(self) -> None:
        try:
            while not self.closed.is_set():
                data = self.outgoing.get()
                if data is None:
                    break
                self.sock.sendall(data)
        except OSError:
            pass
        finally:
            self.close()
            self.sock.close()
            self.server._forget(self)

    def read_loop(self) -> None:
        server = self.server
        try:
            reader = LineReader(self.sock, MAX_LINE)
            reader.deadline = time.monotonic() + server.auth_timeout  # (the whole token line, not each byte)
            lines = reader.lines()
            first = next(lines, None)
            expected = f"token {server.token}".encode()
            if not isinstance(first, bytes) or not hmac.compare_digest(first.strip(), expected):
                log.warning("live: refused a client from %s (bad token)", self.address)
                self.send(answer(0, False, "authentication failed: the first line must be 'token <token>'"))
                return
            reader.deadline = None
            self.sock.settimeout(None)
            self.send(answer(0, True, "sotdrake live: ready"))
            for ident, line in enumerate(lines, start=1):
                if self.closed.is_set():
                    return
                server._handle_line(self, ident, line)
        except OSError:  # includes the authentication timeout
            pass
        finally:
            self.finish()


class CommandServer:
    """Listens on ``host`` (127.0.0.1) at ``port`` (0: any free port); see the module docstring."""

    def __init__(self, vocabulary: Vocabulary, token: str, host: str = HOST, port: int = 0,
                 queue_size: int = 1024, max_connections: int = 8, auth_timeout: float = 5.0,
                 busy_timeout: float = 30.0, max_unsent: int = 20_000):
        if host not in ("127.0.0.1", "::1", "localhost"):
            raise SotError(f"the command server listens on the loopback only, not {host!r}")
        self.vocabulary, self.token = vocabulary, token
        self.queue: queue.Queue[_Request] = queue.Queue(maxsize=queue_size)
        self.max_connections, self.auth_timeout = max_connections, auth_timeout
        self.busy_timeout, self.max_unsent = busy_timeout, max_unsent
        self.counts = ServerCounts()
        self._lock = threading.Lock()
        self._clients: set[_Client] = set()
        self._waiting: dict[tuple[_Client, int], _Request] = {}  # queued, neither taken nor withdrawn
        self.last_tick: float | None = None  # time.monotonic() of the last tick boundary or process()
        self._listener = socket.create_server((host, port))
        self.host, self.port = self._listener.getsockname()[:2]
        self._accepting = threading.Thread(target=self._accept_loop, name="live-accept", daemon=True)
        self._accepting.start()

    # --- network threads -------------------------------------------------------------------
    def _accept_loop(self) -> None:
        while True:
            try:
                sock, address = self._listener.accept()
            except OSError:
                return  # closed
            client = _Client(self, sock, address)
            with self._lock:
                full = len(self._clients) >= self.max_connections
                if not full:
                    self._clients.add(client)
            if full:
                try:
                    sock.sendall(answer(0, False, f"busy: at most {self.max_connections} connections"))
                finally:
                    sock.close()
                continue
            client.writer = threading.Thread(target=client.write_loop, name="live-write", daemon=True)
            client.writer.start()
            threading.Thread(target=client.read_loop, name="live-read", daemon=True).start()

    def _forget(self, client: _Client) -> None:
        with self._lock:
            self._clients.discard(client)

    def _count(self, field: str) -> None:
        with self._lock:
            setattr(self.counts, field, getattr(self.counts, field) + 1)

    def _handle_line(self, client: _Client, ident: int, line: bytes | LineTooLong) -> None:
        """Queue the line for the simulation thread (waiting while the queue is full); a line too
        long and a ``#withdraw`` are answered here, without queueing."""
        if isinstance(line, bytes) and line.startswith(WITHDRAW):
            self._withdraw(client, ident, line)
            return
        self._count("received")
        if isinstance(line, LineTooLong):
            self._count("rejected")
            client.send(answer(ident, False, f"line too long: more than {MAX_LINE} bytes; skipped"))
            return
        client.queued()
        request = _Request(client, ident, line)
        with self._lock:
            self._waiting[client, ident] = request
        try:
            self.queue.put(request, timeout=self.busy_timeout)
        except queue.Full:
            with self._lock:
                self._waiting.pop((client, ident), None)
            self._count("rejected")
            client.send(answer(ident, False, f"busy: {self.queue.maxsize} commands waiting; rejected"), queued=True)

    def _withdraw(self, client: _Client, ident: int, line: bytes) -> None:
        """``#withdraw <id>``: the command of line ``<id>`` is answered now and never applied if it
        is still waiting; else (applied, being applied, unknown) only this line is answered."""
        try:
            target = int(line[len(WITHDRAW):].strip())
        except ValueError:
            client.send(answer(ident, False, "withdraw: expected '#withdraw <id>', the id of an earlier line"))
            return
        with self._lock:
            request = self._waiting.pop((client, target), None)
            if request is not None:
                request.state = "withdrawn"
                self.counts.withdrawn += 1
        if request is None:
            client.send(answer(ident, False, f"withdraw: line {target} is not waiting (answered, being applied, or unknown)"))
            return
        why = f"{self.why_waiting()}; the command was withdrawn, not applied"
        client.send(answer(target, False, why, withdrawn=True), queued=True)
        client.send(answer(ident, True, f"withdrawn: line {target} will not be applied"))

    def why_waiting(self) -> str:
        """Why queued commands are not answered yet, in words: the run has not ticked yet, has not
        ticked for a while, or is ticking with commands ahead."""
        if self.last_tick is None:
            return "the run has not ticked yet (it is starting: numba compiles once after an install)"
        idle = time.monotonic() - self.last_tick
        if idle > 1.0:
            return f"the run has not ticked for {idle:.1f} s (held, paused or stopping)"
        return f"the run is ticking; {self.queue.qsize()} commands are queued, the run applies them in turn"

    def ticked(self) -> None:
        """Called by the simulation thread at each tick boundary (see :meth:`why_waiting`)."""
        self.last_tick = time.monotonic()

    # --- simulation thread -----------------------------------------------------------------
    def process(self, context: Context, deadline: float, minimum: int = 1) -> int:
        """Read, check and apply queued commands to ``context`` until ``time.monotonic() ≥
        deadline`` (at least ``minimum`` if queued); returns how many were handled. All the work
        of a command (parsing included) is done here, so the caller's deadline bounds it."""
        done = 0
        self.ticked()
        while done < minimum or time.monotonic() < deadline:
            try:
                request = self.queue.get_nowait()
            except queue.Empty:
                break
            with self._lock:
                if request.state == "withdrawn":
                    continue  # (already answered)
                request.state = "taken"
                self._waiting.pop((request.client, request.ident), None)
            done += 1
            ok, text = self.handle(request.line, context)
            self._count("accepted" if ok else "rejected")
            request.client.send(answer(request.ident, ok, text), queued=True)
        return done

    def handle(self, line: bytes, context: Context) -> tuple[bool, str]:
        """One command line: ``(True, answer)`` or ``(False, why it was refused)``."""
        try:
            text = line.decode("utf-8")
        except UnicodeDecodeError:
            return False, "not UTF-8 text"
        try:
            prepared = self.vocabulary.prepare(parse_command(text))
        except SotError as error:
            return False, str(error)
        return apply(prepared, context)

    def close(self, flush: float = 1.0) -> None:
        """Stop listening; send the answers already due (for up to ``flush`` s), then drop every
        connection."""
        try:  # (close() alone does not wake the thread waiting in accept(): shut the socket down first)
            self._listener.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        try:
            self._listener.close()
        except OSError:
            pass
        if self._accepting is not threading.current_thread():
            self._accepting.join(1.0)
        with self._lock:
            clients = list(self._clients)
        for client in clients:
            try:
                client.outgoing.put_nowait(None)
            except queue.Full:
                pass
        deadline = time.monotonic() + flush
        for client in clients:
            if client.writer is not None:
                client.writer.join(max(0.0, deadline - time.monotonic()))
            client.close()


def apply(prepared: Prepared, context: Context) -> tuple[bool, str]:
    """``(True, answer)``, or ``(False, error)`` when the API refuses: its exception's message."""
    try:
        return True, prepared(context)
    except (SotError, ValueError, TypeError, KeyError, RuntimeError, OverflowError) as error:
        return False, str(error) or type(error).__name__
    except Exception as error:  # never let a command stop the run
        log.exception("live: %s failed", prepared)
        return False, f"{type(error).__name__}: {error}"
