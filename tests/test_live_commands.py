"""Live commands without a live run: the grammar, the allow-list, the framing, the connection file
and the server (in this process, over a real 127.0.0.1 socket)."""

import os
import socket
import stat
import time

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from sotdrake.exceptions import CommandRejected, InvalidInput, NotFound, SotError, StackError
from sotdrake.live.connection import Connection, read_connection, write_connection
from sotdrake.live.framing import LineReader, LineTooLong
from sotdrake.live.grammar import MAX_CHARACTERS, Command, EntityRef, parse_command
from sotdrake.live.server import CommandServer, ServerCounts
from sotdrake.live.shell import Client
from sotdrake.live.vocabulary import Vocabulary
from sotdrake.scenarios import talos_appli

HOSTILE = [
    "__import__('os').system('touch X')",
    "sot.__class__.__init__",
    "sot.__class__.__init__()",
    "sot.__dict__.clear()",
    "sot.push(__import__)",
    "sot.push(sot.__class__)",
    "sot.push(taskRH.task.name)",  # attribute walk in an argument
    "sot.push('task' + 'rh')",
    "sot.push(x[0])",
    "sot.push(*names)",
    "sot.push(**names)",
    "(lambda: 0)()",
    "sot.push([n for n in 'ab'])",
    "sot.push(f'{sot}')",
    "sot.push(b'taskrh')",
    "sot.push(1j)",
    "sot.push(x := 1)",
    "sot.push('taskrh'); import os",
    "import os",
    "sot.push",
    "sot",
    "1 + 1",
    "a.b.c.d()",
    "getattr(sot, 'push')('taskrh')[0]",
    "sot.push(-'a')",
    "sot.push(not 1)",
    "sot.push(1 if 1 else 2)",
    "sot.push('\0')\0",
    "(" * 500 + ")" * 500,
    "",
    "sot.push('" + "a" * MAX_CHARACTERS + "')",
]


def test_grammar_reads_the_sot_vocabulary():
    assert parse_command("sot.push('taskrh')") == Command("sot", "push", ("taskrh",))
    assert parse_command("  sot.pop() ") == Command("sot", "pop")
    goto = parse_command("gotoNd(taskRH, (0.5, -0.2, 1.0), '111', (4.9, 0.9, 0.01, 0.9))")
    assert goto == Command("", "gotoNd", (EntityRef("taskRH"), (0.5, -0.2, 1.0), "111", (4.9, 0.9, 0.01, 0.9)))
    assert parse_command("taskRH.gain.setConstant(10)") == Command("taskRH.gain", "setConstant", (10,))
    assert parse_command("gotoNd(taskRH, [1, +2, -3], gain=3, selec=None)").kwargs == (("gain", 3), ("selec", None))
    nested = parse_command("attime(2.5, sot.push('taskrh'))")
    assert nested.args == (2.5, Command("sot", "push", ("taskrh",)))
    assert str(goto) == "gotoNd(taskRH, (0.5, -0.2, 1.0), '111', (4.9, 0.9, 0.01, 0.9))"


@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_grammar_rejects_code(text, vocabulary):
    """Everything that is not one whitelisted call is refused by the grammar, or (a function that
    is not offered, such as getattr) by the allow-list; nothing is evaluated."""
    with pytest.raises(SotError):
        vocabulary.prepare(parse_command(text))
    assert not os.path.exists("X")


@pytest.fixture(scope="module")
def appli():
    module = talos_appli
    return module.build_diagram(push_time=None)


@pytest.fixture(scope="module")
def vocabulary(appli):
    return Vocabulary(appli.diagram, appli)


@pytest.fixture
def context(appli):
    simulator = Simulator(appli.diagram)
    simulator.Initialize()
    return simulator.get_mutable_context()


def run(vocabulary, context, text):
    return vocabulary.prepare(parse_command(text))(context)


def test_commands_apply_through_the_api(vocabulary, context, appli):
    sot = appli.sot
    assert run(vocabulary, context, "sot.stack()") == "['taskcontactRF', 'taskcontactLF', 'taskcom']"
    assert run(vocabulary, context, "sot.push(taskRH)") == "ok"  # the meta task stands for its task
    assert sot.stack(context)[-1] == "taskrh" and sot.stack() == ["taskcontactRF", "taskcontactLF", "taskcom"]
    run(vocabulary, context, "sot.up('taskrh')")
    run(vocabulary, context, "sot.rm('taskrh')")  # sot-dyninv's name for remove
    assert "taskrh" not in sot.stack(context)
    run(vocabulary, context, "sot.push(taskRH)")
    run(vocabulary, context, "sot.up('taskrh')")
    assert sot.stack(context) == ["taskcontactRF", "taskcontactLF", "taskrh", "taskcom"]
    run(vocabulary, context, "gotoNd(taskRH, (0.4, -0.3, 0.9), '111', (4.9, 0.9, 0.01, 0.9))")
    desired = appli.taskRH.featureDes.settings(context).position.translation()
    np.testing.assert_allclose(desired, [0.4, -0.3, 0.9])
    assert appli.taskRH.gain.settings(context).coefficients(0.0) == pytest.approx(4.9)
    a, b, c = (float(x.split("=")[1]) for x in run(vocabulary, context, "gainrh.coefficients()").strip(")").split(", "))
    assert (a, c) == (4.0, 0.9) and b == pytest.approx(-np.log(0.9) / 0.01)  # setByPoint(4.9, 0.9, 0.01, 0.9)
    run(vocabulary, context, "taskRH.gain.setConstant(2)")
    assert appli.taskRH.gain.settings(context).coefficients(1.0) == 2.0
    run(vocabulary, context, "gainrh.set(4, 1, 5)")
    assert appli.taskRH.gain.settings(context).coefficients(np.linalg.norm([3, 3, 3])) == pytest.approx(1.00052, abs=1e-5)
    run(vocabulary, context, "taskRH.selec('011')")
    assert appli.taskRH.feature.settings(context).selection == "011"
    run(vocabulary, context, "featurecom_ref.setReference((0.0, 0.0, 0.8))")
    np.testing.assert_allclose(appli.taskCom.featureDes.settings(context).errorIN, [0, 0, 0.8])
    run(vocabulary, context, "taskCom.keep()")
    assert appli.taskCom.featureDes.settings(context).errorIN[2] == pytest.approx(appli.robot.dynamic.com_at(
        appli.robot.device.position(context))[2])
    assert "sot (SOT) at t = 0.0000 s" in run(vocabulary, context, "displaySignals(sot)")
    assert "out control" in run(vocabulary, context, "sot.displaySignals()")
    error = run(vocabulary, context, "signal(featurerh, 'error')")
    assert error.startswith("[") and len(error.strip("[]").split()) == 2  # '011': two rows
    assert "taskrh" in run(vocabulary, context, "entities()")
    assert run(vocabulary, context, "stack()") == repr(sot.stack(context))
    assert "gotoNd(task, position, selec=None, gain=None)" in run(vocabulary, context, "help()")


def _discrete_state(context) -> np.ndarray:
    """Every discrete state group of the diagram, one vector."""
    discrete = context.get_discrete_state()
    return np.concatenate([discrete.get_vector(i).CopyToVector() for i in range(discrete.num_groups())])


@pytest.mark.parametrize("text, error", [
    ("nobody.push('taskrh')", NotFound),
    ("sot.nope()", CommandRejected),
    ("sot.setControlSelection(None)", CommandRejected),  # not offered live
    ("sot.push('nope')", NotFound),
    ("sot.push('taskcom')", StackError),
    ("sot.rmContact('taskcom')", StackError),
    ("sot.push(3)", CommandRejected),
    ("sot.push(taskRH, taskCom)", CommandRejected),
    ("sot.push(name='taskrh')", CommandRejected),
    ("sot.push()", CommandRejected),
    ("gainrh.setConstant('ten')", CommandRejected),
    ("gainrh.setConstant(True)", CommandRejected),
    ("gainrh.setConstant(-1)", InvalidInput),
    ("gainrh.setConstant(10 ** 400)", CommandRejected),
    ("gainrh.setConstant((1, 2))", CommandRejected),
    ("gotoNd(taskRH, (0.5, 'a', 1.0))", CommandRejected),
    ("gotoNd(taskRH, (0.5, 1.0))", InvalidInput),
    ("gotoNd(taskRH, (0.5, -0.2, 1.0), '1111111')", InvalidInput),
    ("gotoNd(taskRH, (0.5, -0.2, 1.0), '111', (1, 2))", InvalidInput),
    ("gotoNd(sot, (0.5, -0.2, 1.0))", CommandRejected),
    ("gotoNd('taskRH', (0.5, -0.2, 1.0))", CommandRejected),
    ("gotoNd(taskRH, ((1, 2), 3))", CommandRejected),
    ("gotoNd(taskRH, tuple(range(10 ** 6)))", CommandRejected),
    ("taskRH.feature.frame('sideways')", InvalidInput),
    ("signal(sot, 'nope')", NotFound),
    ("displaySignals(nobody)", CommandRejected),
    ("attime(-1, sot.pop())", CommandRejected),
    ("attime(1, 'sot.pop()')", CommandRejected),
    ("attime(1, attime(2, sot.pop()))", CommandRejected),
    ("attime(1, sot.nope())", CommandRejected),
])
def test_rejected_commands_change_nothing(vocabulary, context, appli, text, error):
    before = {name: _settings(system, context) for name, system in _entities(appli)}
    state = _discrete_state(context)
    with pytest.raises(error):
        run(vocabulary, context, text)
    assert {name: _settings(system, context) for name, system in _entities(appli)} == before
    np.testing.assert_array_equal(_discrete_state(context), state)


def _entities(appli):
    from sotdrake.entity import Entity

    return [(s.get_name(), s) for s in appli.diagram.GetSystems() if isinstance(s, Entity)]


def _settings(system, context):
    return repr(system.settings(context))


def test_prepare_touches_no_context(vocabulary):
    """Checking a command needs no context: rejections happen before the simulation sees them."""
    prepared = vocabulary.prepare(parse_command("sot.push(taskRH)"))
    assert prepared.values == ("taskrh",)
    with pytest.raises(CommandRejected):
        vocabulary.prepare(parse_command("sot.push(taskRH, 1)"))


def test_line_reader_bounds_lines():
    a, b = socket.socketpair()
    with a, b:
        a.sendall(b"one\n" + b"x" * 200_000 + b"\ntwo\n" + b"y" * 999 + b"\n")
        a.shutdown(socket.SHUT_WR)
        lines = list(LineReader(b, limit=1000).lines())
    assert lines[0] == b"one" and isinstance(lines[1], LineTooLong) and lines[2] == b"two"
    assert lines[3] == b"y" * 999 and len(lines) == 4  # 999 bytes and the newline: exactly the limit


def test_connection_file_is_private(tmp_path):
    connection = Connection("127.0.0.1", 1234, "ab" * 32, 42)
    path = write_connection(tmp_path / "run" / "live.json", connection)
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert read_connection(path) == connection
    path.chmod(0o644)
    with pytest.raises(InvalidInput, match="only the owner"):
        read_connection(path)


def test_server_token_framing_and_answers(vocabulary, context, appli):
    server = CommandServer(vocabulary, "secret-token", queue_size=4)
    try:
        assert server.host == "127.0.0.1"
        # a wrong token: refused, connection closed, nothing queued
        with socket.create_connection((server.host, server.port), timeout=60) as sock:
            sock.sendall(b"token wrong\nsot.pop()\n")
            reply = sock.makefile("rb").read()
        assert b"authentication failed" in reply and b"ready" not in reply and server.queue.empty()
        connection = Connection(server.host, server.port, "secret-token", os.getpid())
        with Client(connection, timeout=60) as client:
            for broken in ("sot.stack()\nsot.pop()", b"sot.pop()\r\n", "sot.stack()\r"):
                with pytest.raises(InvalidInput, match="one line"):
                    client.send_line(broken)  # (two commands under one id would shift every answer after)
            huge = client.send_line(b"sot.push('" + b"a" * 1_000_000 + b"')")
            assert "line too long" in client.receive(huge)["error"]  # answered by the reader, not queued
            lines = [b"sot.push('\xff')", b"__import__('os').system('ls')", b"sot.stack()", b"sot.pop()"]
            ids = [client.send_line(line) for line in lines]
            deadline = time.monotonic() + 10
            while server.queue.qsize() < len(lines) and time.monotonic() < deadline:
                time.sleep(0.01)
            assert server.process(context, time.monotonic() + 1.0) == len(lines)
            answers = [client.receive(i) for i in ids]
            assert [a["ok"] for a in answers] == [False, False, True, True]
            assert "UTF-8" in answers[0]["error"] and "the called thing must be a name" in answers[1]["error"]
            assert answers[2] == {"id": ids[2], "ok": True, "answer": "['taskcontactRF', 'taskcontactLF', 'taskcom']"}
            assert appli.sot.stack(context) == ["taskcontactRF", "taskcontactLF"]
            assert server.counts == ServerCounts(received=5, accepted=2, rejected=3)
    finally:
        server.close()


def test_a_closed_server_stops_listening_and_lets_go_of_its_run(vocabulary):
    import gc
    import threading
    import weakref

    server = CommandServer(vocabulary, "secret-token")
    host, port, accepting = server.host, server.port, server._accepting
    server.close()
    accepting.join(30)  # (close() waits 1 s for it; a loaded host may take longer)
    assert not accepting.is_alive()
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection((host, port), timeout=5).close()
    gone = weakref.ref(server)
    del server
    gc.collect()
    assert gone() is None and "live-accept" not in [t.name for t in threading.enumerate()]


@pytest.mark.filterwarnings("ignore:overflow encountered")
def test_a_run_broken_mid_way_stops_and_writes_its_files(tmp_path, appli, monkeypatch):
    """A run that fails at a tick after a valid command (here the solver is made to fail once the
    command is answered, since every absurd value is refused at the command) stops at the failing
    tick, writes the trace and summary, and ``run_live`` raises."""
    import json
    import threading

    from sotdrake.exceptions import SolverError
    from sotdrake.hqp.stack_paths import CASCADE
    from sotdrake.live.runner import run_live

    out = tmp_path / "out"
    answers = []
    broken = threading.Event()
    solve = CASCADE.factorize

    def failing_solve(*args, **kwargs):
        if broken.is_set():
            raise SolverError("non-finite control (injected by the test)")
        return solve(*args, **kwargs)

    monkeypatch.setattr(CASCADE, "factorize", failing_solve)

    def poke():
        try:
            while not (out / "live.json").exists():
                time.sleep(0.01)
            with Client(out / "live.json", timeout=120.0) as client:
                answers.append(client.command("sot.push('taskrh')"))
                answers.append(client.command("gotoNd(taskRH, (1e300, 0, 0), '111', 1000)"))  # refused: beyond the ranges
            broken.set()
        except Exception as error:  # (reported by the test, not lost with the thread)
            answers.append(error)

    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    threading.Thread(target=poke, daemon=True).start()
    try:
        run_live(appli, out, duration=120.0)
    except SotError as error:
        assert "non-finite" in str(error)
    else:
        pytest.fail(f"the run was not broken; the commands got {answers}")
    assert [a["ok"] for a in answers] == [True, False], answers
    summary = json.loads((out / "summary.json").read_text())
    assert "non-finite" in summary["live"]["error"] and summary["duration_s"] < 120.0
    assert (out / "trace.npz").is_file() and not (out / "live.json").exists()


def test_attime_checks_the_values_now_on_a_copy_and_leaves_the_rest_to_its_time(vocabulary, context, appli):
    """A command whose values are refused (a negative gain, a wrong target size) is refused when it
    is scheduled, not at T where only a log line would say so; one that depends on the stack at T
    (a push) is scheduled; the trial changes nothing in the run's context."""
    scheduled = []
    vocabulary.set_scheduler(lambda time, prepared: scheduled.append((time, str(prepared))) or "ok")
    try:
        before = {name: _settings(system, context) for name, system in _entities(appli)}
        with pytest.raises(CommandRejected, match="a gain must be ≥ 0"):
            run(vocabulary, context, "attime(1, gainrh.setConstant(-5))")
        with pytest.raises(CommandRejected, match="attime: gotoNd"):
            run(vocabulary, context, "attime(1, gotoNd(taskRH, (0.1, 0.2), '111', 3))")
        with pytest.raises(CommandRejected, match="nope"):
            run(vocabulary, context, "attime(1, sot.push('nope'))")  # no task of that name, now or at T
        with pytest.raises(CommandRejected, match="nope"):
            run(vocabulary, context, "attime(1, signal(sot, 'nope'))")
        for query in ("stack()", "sot.stack()", "time()", "displaySignals(sot)", "help()"):
            with pytest.raises(CommandRejected, match="only answers a question"):
                run(vocabulary, context, f"attime(1, {query})")
        assert scheduled == []
        run(vocabulary, context, "attime(1, gainrh.setConstant(3))")
        run(vocabulary, context, "attime(1, sot.remove('taskrh'))")  # not in the stack now: may be at T
        assert [time for time, _ in scheduled] == [1.0, 1.0]
        assert {name: _settings(system, context) for name, system in _entities(appli)} == before
    finally:
        vocabulary.set_scheduler(None)
