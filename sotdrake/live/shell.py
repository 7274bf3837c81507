"""``sotdrake-shell``: the client of a live run, at a prompt or one command at a time.

    sotdrake-shell                               # prompt: sot> sot.push('taskrh')
    sotdrake-shell "sot.push('taskrh')"          # one-shot: prints the answer; exit 1 if refused
    sotdrake-shell --connection out/appli/live.json "displaySignals(sot)"

It reads the run's connection file (mode 0600; default: the latest run of this user, see
:func:`~.connection.default_path`), connects to 127.0.0.1 and sends the token, then the commands.
:class:`Client` is the same thing as a library (the tests use it).
"""

from __future__ import annotations

import argparse
import socket
import sys
from pathlib import Path

from ..exceptions import InvalidInput, SotError
from .connection import Connection, default_path, read_connection
from .framing import MAX_LINE, LineReader, LineTooLong, decode_answer


class Client:
    """A connection to a live run; :meth:`command` sends one line and returns its answer."""

    def __init__(self, connection: Connection | Path | str | None = None, timeout: float = 10.0):
        if not isinstance(connection, Connection):
            connection = read_connection(Path(connection) if connection is not None else default_path())
        self.connection = connection
        self.sock = socket.create_connection((connection.host, connection.port), timeout=timeout)
        self._lines = LineReader(self.sock, 64 * MAX_LINE).lines()
        self._sent = 0
        self._early: dict[int, dict] = {}
        self.send_line(f"token {connection.token}")
        self._sent = 0
        hello = self._next()
        if not hello["ok"]:
            raise SotError(hello["error"])

    def send_line(self, text: str | bytes) -> int:
        """Send one line (no answer awaited); returns its id. A line break inside is refused
        (:class:`InvalidInput`): the run would read two commands, answered under two ids."""
        data = text.encode() if isinstance(text, str) else text
        if b"\n" in data or b"\r" in data:
            raise InvalidInput(f"a command is one line; this one holds a line break: {data[:80]!r}")
        self.sock.sendall(data + b"\n")
        self._sent += 1
        return self._sent

    def receive(self, ident: int) -> dict:
        """The answer ``{"id", "ok", "answer" | "error"}`` to line ``ident``."""
        while ident not in self._early:
            message = self._next()
            self._early[message["id"]] = message
        return self._early.pop(ident)

    def command(self, text: str) -> dict:
        return self.receive(self.send_line(text))

    def _next(self) -> dict:
        line = next(self._lines, None)
        if line is None or isinstance(line, LineTooLong):
            raise SotError("the live run closed the connection")
        return decode_answer(line)

    def close(self) -> None:
        self.sock.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _show(message: dict) -> bool:
    if message["ok"]:
        print(message["answer"])
    else:
        print(f"error: {message['error']}", file=sys.stderr)
    return bool(message["ok"])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="sotdrake-shell", description=__doc__.split("\n\n")[0])
    parser.add_argument("commands", nargs="*", help="commands to send (none: interactive prompt)")
    parser.add_argument("--connection", type=Path, default=None,
                        help=f"the run's connection file (default: {default_path()})")
    parser.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for an answer")
    args = parser.parse_args(argv)
    try:
        client = Client(args.connection, args.timeout)
    except (SotError, OSError) as error:
        print(f"sotdrake-shell: {error}", file=sys.stderr)
        return 2
    with client:
        try:
            if args.commands:
                ok = True
                for text in args.commands:
                    ok = _show(client.command(text)) and ok
                return 0 if ok else 1
            return _prompt(client)
        except (SotError, OSError) as error:
            print(f"sotdrake-shell: {error}", file=sys.stderr)
            return 2


def _prompt(client: Client) -> int:
    try:
        import readline  # noqa: F401  (history and line editing at the prompt)
    except ImportError:  # pragma: no cover - not on every platform
        pass
    print("sotdrake live shell: SoT commands such as sot.push('taskrh'); help() lists them; Ctrl-D quits")
    while True:
        try:
            text = input("sot> ")
        except (EOFError, KeyboardInterrupt):
            print()
            return 0
        if text.strip():
            _show(client.command(text))


if __name__ == "__main__":
    sys.exit(main())
