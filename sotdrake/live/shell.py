"""``sotdrake-shell``: the client of a live run, at a prompt or one command at a time.

    sotdrake-shell                               # prompt: sot> sot.push('taskrh')
    sotdrake-shell "sot.push('taskrh')"          # one-shot: prints the answer; exit 1 if refused
    sotdrake-shell --connection out/appli/live.json "displaySignals(sot)"

It reads the run's connection file (mode 0600; default: the latest run of this user, see
:func:`~.connection.default_path`), connects to 127.0.0.1 and sends the token, then the commands.
:class:`Client` is the same thing as a library (the tests use it).

A command not answered within ``--timeout`` seconds (say, the run has not ticked yet: numba compiles
before the first tick) is withdrawn: the run confirms that it will never apply it, and the shell
says so (exit status 2). If the run cannot confirm it (it does not answer at all), the shell says
that the command may still be applied.
"""

from __future__ import annotations

import argparse
import socket
import sys
from pathlib import Path

from ..exceptions import InvalidInput, SotError
from .connection import Connection, default_path, read_connection
from .framing import MAX_LINE, LineReader, LineTooLong, decode_answer


class NotApplied(SotError):
    """The client stopped waiting (a time-out, Ctrl-C) and the run confirmed that the command was
    withdrawn: it is never applied."""


class Client:
    """A connection to a live run; :meth:`command` sends one line and returns its answer.

    ``timeout``: seconds to wait for each answer; then the command is withdrawn (:meth:`receive`),
    and ``withdraw_wait`` seconds more are given to the run to confirm it."""

    def __init__(self, connection: Connection | Path | str | None = None, timeout: float = 10.0,
                 withdraw_wait: float = 10.0):
        if not isinstance(connection, Connection):
            connection = read_connection(Path(connection) if connection is not None else default_path())
        self.connection, self.timeout, self.withdraw_wait = connection, timeout, withdraw_wait
        self.sock = socket.create_connection((connection.host, connection.port), timeout=timeout)
        self._reader = LineReader(self.sock, 64 * MAX_LINE)
        self._lines = self._reader.lines()
        self._sent = 0
        self._early: dict[int, dict] = {}
        self._ignored: set[int] = set()  # withdraw lines, whose own answers nobody awaits
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
        """The answer ``{"id", "ok", "answer" | "error"}`` to line ``ident``; with no answer within
        ``timeout`` s, :meth:`withdraw`'s."""
        try:
            return self._await(ident)
        except TimeoutError:
            return self.withdraw(ident, f"no answer within {self.timeout:g} s")

    def _await(self, ident: int) -> dict:
        while ident not in self._early:
            message = self._next()
            if message.get("id") in self._ignored:
                self._ignored.discard(message["id"])
            else:
                self._early[message["id"]] = message
        return self._early.pop(ident)

    def withdraw(self, ident: int, waited: str) -> dict:
        """Withdraw line ``ident`` (``#withdraw <ident>``) and wait ``withdraw_wait`` s for the run's
        word: :class:`NotApplied` when the run confirms it will never apply the command, the
        command's answer if the run had begun applying it, else :class:`~sotdrake.exceptions.SotError`
        (the command may still be applied). ``waited``: what happened, to begin the messages with."""
        self._lines = self._reader.lines()  # (the interrupted one is closed; the reader keeps what it read)
        self.sock.settimeout(self.withdraw_wait)
        try:
            self._ignored.add(self.send_line(f"#withdraw {ident}"))
            message = self._await(ident)
        except (TimeoutError, KeyboardInterrupt):
            self._lines = self._reader.lines()
            raise SotError(f"{waited}, and the run did not confirm that the command was withdrawn: "
                           "it may still be applied when the run ticks") from None
        finally:
            self.sock.settimeout(self.timeout)
        if message.get("withdrawn"):
            raise NotApplied(f"{waited}: {message['error']}")
        return message

    def command(self, text: str) -> dict:
        """Send ``text`` and return its answer (:meth:`receive`)."""
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


def _ask(client: Client, text: str) -> dict:
    """``client.command(text)``; on Ctrl-C while waiting, the command is withdrawn (:meth:`Client.withdraw`)."""
    ident = client.send_line(text)
    try:
        return client.receive(ident)
    except KeyboardInterrupt:
        return client.withdraw(ident, "interrupted before the answer")


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
    parser.add_argument("--timeout", type=float, default=10.0,
                        help="seconds to wait for an answer; then the command is withdrawn (never applied once the run confirms)")
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
                    ok = _show(_ask(client, text)) and ok
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
            try:
                _show(_ask(client, text))
            except NotApplied as error:
                print(f"sotdrake-shell: {error}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
