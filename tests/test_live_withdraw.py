"""A command the client stopped waiting for is never applied: the client withdraws it, the run
confirms, and when the run ticks at last the command is skipped.

The runs here are held on purpose (the simulator is not advanced while the client waits), as a run
is while numba compiles before its first tick. Nothing depends on the host's speed: the client's
time-outs are short because the run is held for as long as the test wants, and every other wait is
generous and ends on an event.
"""

import json
import os
import socket
import threading
import time

import pytest

from sotdrake.exceptions import SotError
from sotdrake.live.connection import Connection, write_connection
from sotdrake.live.runner import LiveRun
from sotdrake.live.server import CommandServer
from sotdrake.live.shell import Client, NotApplied, main
from sotdrake.scenarios import talos_appli

WAIT_S = 120.0  # the longest wait for an answer the run gives at once (a loaded host answers in far less)
STACK = ["taskcontactRF", "taskcontactLF", "taskcom"]


@pytest.fixture(scope="module")
def appli():
    return talos_appli.build_diagram(push_time=None)


@pytest.fixture
def live(appli):
    run = LiveRun(appli.diagram, appli.robot.dt, appli, realtime_rate=1000.0)
    try:
        yield run
    finally:
        run.server.close()


def _connection(server: CommandServer) -> Connection:
    return Connection(server.host, server.port, server.token, os.getpid())


def test_a_command_the_client_gave_up_on_is_not_applied_when_the_run_ticks(live, appli):
    """Before the first tick (numba compiling): the client gives up, the run confirms the withdrawal,
    and the run's first ticks skip the command; ``status()`` counts it as withdrawn."""
    with Client(_connection(live.server), timeout=0.5, withdraw_wait=WAIT_S) as client:
        with pytest.raises(NotApplied, match=r"no answer within 0.5 s: the run has not ticked yet .*withdrawn, not applied"):
            client.command("sot.pop()")
    live.run(0.003)  # the first ticks: the queued pop is skipped
    assert appli.sot.stack(live.context) == STACK
    status = json.loads(live.status())
    assert status["ticks"] > 0 and status["withdrawn"] == 1
    assert (status["received"], status["accepted"], status["rejected"]) == (1, 0, 0)


def test_a_held_run_withdraws_and_the_connection_goes_on(live, appli):
    """After ticks, a held run (not advanced): the answer says how long it has not ticked; later
    commands on the same connection are answered under their own ids."""
    server, context = live.server, live.context
    live.simulator.Initialize()
    server.process(context, 0.0, minimum=0)  # a tick boundary, then the run is held
    with Client(_connection(server), timeout=1.5, withdraw_wait=WAIT_S) as client:
        with pytest.raises(NotApplied, match=r"the run has not ticked for .* s \(held"):
            client.command("sot.pop()")
        ident = client.send_line("sot.stack()")
        _until(lambda: server.queue.qsize() == 2)  # (the withdrawn pop, then the stack)
        assert server.process(context, 0.0) == 1  # the withdrawn pop is skipped, not counted
        assert client.receive(ident) == {"id": ident, "ok": True, "answer": str(STACK)}
    assert appli.sot.stack(context) == STACK
    assert (server.counts.accepted, server.counts.withdrawn) == (1, 1)


def test_a_command_being_applied_is_not_withdrawn_and_its_answer_comes(live, appli):
    """A command the run has begun to apply when the client gives up: the withdrawal is refused
    and the client returns the command's own answer (it was applied)."""
    server, context = live.server, live.context
    live.simulator.Initialize()
    release, withdraw, handle = threading.Event(), server._withdraw, server.handle

    def withdraw_then_release(*args):
        withdraw(*args)
        release.set()

    def slow_handle(line, context):
        release.wait(WAIT_S)
        return handle(line, context)

    server._withdraw = withdraw_then_release  # type: ignore[method-assign]
    server.handle = slow_handle  # type: ignore[method-assign]
    try:
        with Client(_connection(server), timeout=0.5, withdraw_wait=WAIT_S) as client:
            ident = client.send_line("sot.pop()")
            _until(lambda: not server.queue.empty())  # (the reader queued the line)
            worker = threading.Thread(target=lambda: server.process(context, 0.0, minimum=1))
            worker.start()
            _until(lambda: not server._waiting)  # (the simulation thread took it)
            answer = client.receive(ident)
            worker.join(WAIT_S)
        assert answer["id"] == ident and answer["ok"], answer
        assert appli.sot.stack(context) == STACK[:-1] and server.counts.withdrawn == 0
    finally:
        release.set()


def _until(condition) -> None:
    deadline = time.monotonic() + WAIT_S
    while not condition():
        assert time.monotonic() < deadline, "the condition did not come true"
        time.sleep(0.01)


def test_the_shell_says_the_command_was_not_applied(live, appli, tmp_path, capsys):
    path = write_connection(tmp_path / "live.json", live.connection)
    assert main(["--connection", str(path), "--timeout", "0.5", "stop()"]) == 2
    error = capsys.readouterr().err
    assert "sotdrake-shell: no answer within 0.5 s: the run has not ticked yet" in error
    assert "the command was withdrawn, not applied" in error
    live.run(0.003)  # stop() was withdrawn: the run goes on to its duration
    assert json.loads(live.status())["t"] == pytest.approx(0.003) and appli.sot.stack(live.context) == STACK


def test_ctrl_c_while_waiting_withdraws_the_command(live, appli, monkeypatch):
    from sotdrake.live import shell

    def interrupted(self, ident):
        raise KeyboardInterrupt

    with Client(_connection(live.server), timeout=WAIT_S, withdraw_wait=WAIT_S) as client:
        monkeypatch.setattr(Client, "receive", interrupted)
        with pytest.raises(NotApplied, match="interrupted before the answer: the run has not ticked yet"):
            shell._ask(client, "sot.pop()")
    live.run(0.003)
    assert appli.sot.stack(live.context) == STACK and json.loads(live.status())["withdrawn"] == 1


def test_a_run_that_does_not_confirm_is_reported_as_unknown():
    """A server that never answers (not even the withdrawal, as one without ``#withdraw``): the
    client says the command may still be applied."""
    listener = socket.create_server(("127.0.0.1", 0))
    lines: list[bytes] = []

    def serve() -> None:
        sock, _ = listener.accept()
        with sock, sock.makefile("rb") as reader:
            reader.readline()
            sock.sendall(b'{"id": 0, "ok": true, "answer": "ready"}\n')
            lines.extend(iter(reader.readline, b""))

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    connection = Connection("127.0.0.1", listener.getsockname()[1], "t", os.getpid())
    try:
        with Client(connection, timeout=0.2, withdraw_wait=0.2) as client:
            with pytest.raises(SotError, match="may still be applied") as raised:
                client.command("sot.pop()")
            assert not isinstance(raised.value, NotApplied)
        thread.join(WAIT_S)
        assert lines == [b"sot.pop()\n", b"#withdraw 1\n"]
    finally:
        listener.close()
