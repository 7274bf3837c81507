"""The wire format of the command channel: UTF-8 lines, at most :data:`MAX_LINE` bytes each.

Client → server: the first line is ``token <hex>``, then one command per line. Server → client: one
JSON object per line, ``{"id": k, "ok": true, "answer": "..."}`` or ``{"id": k, "ok": false,
"error": "..."}``, where ``k`` counts the client's lines after the token (1, 2, …); answers to
rejected lines may overtake answers to accepted ones, so the client matches them by ``id``.

A client that stops waiting sends ``#withdraw <k>`` (a line of its own, with its own id): the server
answers at once. If line ``k`` was still waiting for a tick, it is answered ``{"id": k, "ok":
false, "error": "...", "withdrawn": true}`` and never applied, and the withdraw line is answered
``ok``; if it was already answered or being applied, the withdraw line is answered ``ok`` false and
line ``k`` gets its usual answer. A server that does not know ``#withdraw`` refuses it as a command.

:class:`LineReader` never holds more than ``MAX_LINE`` bytes plus one ``recv``: a longer line is
reported as too long and skipped up to its end, as it arrives.
"""

from __future__ import annotations

import json
import socket
import time
from collections.abc import Iterator

#: Longest line accepted, newline included (bytes).
MAX_LINE = 64 * 1024
_RECV = 16 * 1024
#: The start of a line that withdraws an earlier one: ``#withdraw <id>`` (never a command: ``#`` starts a comment).
WITHDRAW = b"#withdraw "


class LineTooLong(Exception):
    """Stands for a line that was longer than ``MAX_LINE`` bytes (already skipped)."""


class LineReader:
    """Lines from a socket, each at most ``limit`` bytes; too long ones yield :class:`LineTooLong`."""

    def __init__(self, sock: socket.socket, limit: int = MAX_LINE):
        self.sock, self.limit = sock, limit
        self._buffer = bytearray()
        self._skipping = False
        #: ``time.monotonic()`` after which reading raises ``TimeoutError`` (None: no deadline): one
        #: deadline for a whole line, however slowly its bytes come
        self.deadline: float | None = None

    def lines(self) -> Iterator[bytes | LineTooLong]:
        """Yield each line (without its newline) until the peer closes the connection."""
        while True:
            if self.deadline is not None:
                remaining = self.deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError("no complete line before the deadline")
                self.sock.settimeout(remaining)
            chunk = self.sock.recv(_RECV)
            if not chunk:
                return
            if self._skipping:
                end = chunk.find(b"\n")
                if end < 0:
                    continue
                self._skipping = False
                chunk = chunk[end + 1 :]
            self._buffer += chunk
            while True:
                end = self._buffer.find(b"\n")
                if end < 0:
                    break
                line = bytes(self._buffer[:end])
                del self._buffer[: end + 1]
                yield LineTooLong() if end + 1 > self.limit else line
            if len(self._buffer) >= self.limit:
                self._buffer.clear()
                self._skipping = True
                yield LineTooLong()


def answer(ident: int, ok: bool, text: str, withdrawn: bool = False) -> bytes:
    """One answer line (``withdrawn``: the command was withdrawn by its client, not applied)."""
    message: dict[str, object] = {"id": ident, "ok": ok, ("answer" if ok else "error"): text}
    if withdrawn:
        message["withdrawn"] = True
    return (json.dumps(message) + "\n").encode()


def decode_answer(line: bytes) -> dict:
    return json.loads(line)
