"""A live run in one process (``talos_appli.py --live``), the client in others: the hand task pushed
live moves the hand, ``gotoNd`` changes the target, ``displaySignals`` answers; hostile input is
rejected with no effect while the run goes on; a burst of 10 000 commands keeps real time; Ctrl-C
stops cleanly and writes the trace and summary; headless Chromium shows TALOS in the live Meshcat.

Nothing here depends on the host's speed or load: every wait is for an event (the connection file,
an answer, the simulated time reaching a value), with generous stated time-outs (:data:`ANSWER_S`
for an answer, :data:`START_S` for a run to start, numba's first compilation included), and the
checks are on simulated time. How well a run keeps real time under a burst is measured by
``bench/live.py``, not asserted here. The run's target real-time rate is :data:`RATE`.
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sotdrake.live.burst import measure_burst
from sotdrake.live.shell import Client

pytestmark = pytest.mark.slow  # a live run in another process

ROOT = Path(__file__).resolve().parents[1]
RATE = 0.25
BURST = 10_000
ANSWER_S = 120.0  # the longest wait for one answer (a loaded host answers in well under a second)
START_S = 600.0  # the longest wait for a run to start (imports and numba's first compilation)


class Live:
    def __init__(self, process, out: Path, log: Path):
        self.process, self.out, self.log = process, out, log
        self.client = Client(out / "live.json", timeout=ANSWER_S)

    def ask(self, text: str) -> str:
        answer = self.client.command(text)
        assert answer["ok"], f"{text}: {answer.get('error')}"
        return answer["answer"]

    def status(self) -> dict:
        return json.loads(self.ask("status()"))

    def wait_until(self, t: float, timeout: float = 300.0) -> float:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            now = float(self.ask("time()"))
            if now >= t:
                return now
            time.sleep(0.05)
        raise AssertionError(f"the live run did not reach t = {t} s\n{self.log.read_text()}")

    def vector(self, text: str) -> np.ndarray:
        return np.array(self.ask(text).replace("[", " ").replace("]", " ").split(), dtype=float)


def shell(out: Path, *commands: str) -> subprocess.CompletedProcess:
    """``sotdrake-shell`` in its own process (as the entry point runs it), waiting up to
    :data:`ANSWER_S` for each answer."""
    return subprocess.run([sys.executable, "-m", "sotdrake.live.shell", "--connection", str(out / "live.json"),
                           "--timeout", str(ANSWER_S), *commands],
                          cwd=ROOT, capture_output=True, text=True, timeout=START_S)


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    work = tmp_path_factory.mktemp("live")
    out, log = work / "out", work / "live.log"
    env = dict(os.environ, PYTHONPATH=str(ROOT), XDG_RUNTIME_DIR=str(work))
    with open(log, "w") as log_file:
        process = subprocess.Popen(
            [sys.executable, str(ROOT / "diagrams" / "talos_appli.py"), "--live", "--no-push", "--out", str(out),
             "--rate", str(RATE)],
            cwd=work, env=env, stdout=log_file, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + START_S
    while not ((out / "live.json").exists() and "commands: sotdrake-shell" in log.read_text()):  # (printed after)
        if process.poll() is not None or time.monotonic() > deadline:
            process.kill()
            pytest.fail(f"the live run did not start:\n{log.read_text()}")
        time.sleep(0.2)
    run = Live(process, out, log)
    yield run
    run.client.close()
    if process.poll() is None:
        process.kill()
        process.wait(10)


def test_the_connection_file_is_private_and_the_url_printed_once(live):
    assert oct(os.stat(live.out / "live.json").st_mode & 0o777) == "0o600"
    connection = json.loads((live.out / "live.json").read_text())
    assert connection["host"] == "127.0.0.1" and len(connection["token"]) == 64
    text = live.log.read_text()
    assert text.count(connection["meshcat"]) == 1 and connection["meshcat"].startswith("http://localhost:")


def test_display_signals_answers(live):
    result = shell(live.out, "displaySignals(sot)")
    assert result.returncode == 0, result.stderr
    assert "sot (SOT) at t = " in result.stdout and "out control" in result.stdout and "in  taskcom" in result.stdout
    refused = shell(live.out, "sot.push('nope')")
    assert refused.returncode == 1 and "unknown task 'nope'" in refused.stderr


def test_pushing_the_hand_task_moves_the_hand(live):
    live.wait_until(0.2)
    error0 = np.linalg.norm(live.vector("signal(featurerh, 'error')"))
    assert error0 == pytest.approx(0.414, abs=1e-3)  # the tutorial's start, hand task not pushed
    t = float(live.ask("time()"))
    live.wait_until(t + 0.3)
    assert np.linalg.norm(live.vector("signal(featurerh, 'error')")) == pytest.approx(error0, abs=1e-9)  # holds still
    result = shell(live.out, "sot.push('taskrh')")
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr
    assert live.ask("sot.stack()") == "['taskcontactRF', 'taskcontactLF', 'taskcom', 'taskrh']"
    t = float(live.ask("time()"))
    live.wait_until(t + 1.0)
    error1 = np.linalg.norm(live.vector("signal(featurerh, 'error')"))
    assert error1 < 0.5 * error0  # λ(e) ≥ 0.9 /s: at least e^-0.9 ≈ 0.4 in 1 s
    contact = np.linalg.norm(live.vector("signal(featurecontactRF, 'error')"))
    assert contact < 1e-4  # the feet are held meanwhile


def test_gotoNd_changes_the_target(live):
    if "taskrh" not in live.ask("sot.stack()"):  # (the tests share one run: the hand task may not be pushed yet)
        live.ask("sot.push('taskrh')")
    result = shell(live.out, "gotoNd(taskRH, (0.45, -0.3, 0.9), '111', 5)")
    assert result.returncode == 0, result.stderr
    desired = live.vector("signal(featurerh_ref, 'position')").reshape(4, 4)
    np.testing.assert_allclose(desired[:3, 3], [0.45, -0.3, 0.9])
    error0 = np.linalg.norm(live.vector("signal(featurerh, 'error')"))
    t = float(live.ask("time()"))
    live.wait_until(t + 0.5)
    assert np.linalg.norm(live.vector("signal(featurerh, 'error')")) < 0.2 * error0  # λ = 5 /s: e^-2.5 ≈ 0.08


def _snapshot(live) -> tuple[str, ...]:
    """The settings hostile commands aim at."""
    return tuple(live.ask(text) for text in ("sot.stack()", "sot.contacts()", "gainrh.coefficients()",
                                             "signal(featurerh_ref, 'position')", "signal(featurecom_ref, 'errorIN')"))


HOSTILE = [
    "__import__('os').system('touch X')",
    "sot.__class__.__init__",
    "sot.__class__.__init__(sot, 'x', 3)",
    "sot.push.__globals__",
    "nobody.push('taskrh')",
    "sot.eval('1')",
    "sot.push('taskcom')",           # a duplicate: the API's error
    "sot.push(42)",
    "gainrh.setConstant('fast')",
    "gainrh.setConstant(-3)",
    "gotoNd(taskRH, 'far away')",
    "gotoNd(taskRH, (1, 2))",
    "exec('import os')",
    "sot.clear() or os.system('touch X')",
]


def test_hostile_input_is_rejected_and_the_run_goes_on(live):
    before, t0 = _snapshot(live), float(live.ask("time()"))
    for text in HOSTILE:
        answer = live.client.command(text)
        assert not answer["ok"], text
        result = shell(live.out, text) if text == HOSTILE[0] else None
        assert result is None or (result.returncode == 1 and "error:" in result.stderr)
    huge = live.client.send_line("sot.push('" + "a" * 1_000_000 + "')")
    assert "line too long" in live.client.receive(huge)["error"]
    assert _snapshot(live) == before
    assert not (live.out.parent / "X").exists() and not (ROOT / "X").exists()
    assert float(live.ask("time()")) > t0 and live.process.poll() is None


def test_a_burst_of_commands_is_answered_with_no_effect(live, record_property):
    """10 000 commands sent at once on one connection (accepted queries and every kind of
    refusal mixed): each answered in order, none refused as busy, none with an effect, and the run
    goes on. (The real time it keeps meanwhile is a figure of ``bench/live.py``.)"""
    kinds = ["sot.stack()", "gainrh.setConstant(-1)", "__import__('os').system('touch X')", "sot.up('taskcontactRF')"]
    before, t0 = _snapshot(live), float(live.ask("time()"))
    figures, answers = measure_burst(live.client, kinds, BURST, RATE, 1e-3, idle=2.0)
    assert [a["ok"] for a in answers] == [k % 4 == 0 for k in range(BURST)]
    assert all("busy" not in a.get("error", "") for a in answers)
    assert _snapshot(live) == before and not (live.out.parent / "X").exists()
    record_property("burst", figures)
    print("live burst:", json.dumps(figures))
    live.wait_until(t0 + 0.01)  # the run goes on


def test_attime_schedules_a_command(live):
    if "taskrh" not in live.ask("sot.stack()"):  # (the tests share one run: another may have removed it)
        live.ask("sot.push('taskrh')")
    refused = live.status()["attime_refused"]
    for ahead in (1.0, 4.0, 16.0, 64.0):  # (seconds of simulated time; a loaded host may let T pass first)
        t = float(live.ask("time()"))
        first = live.client.command(f"attime({t + ahead:.3f}, sot.remove('taskrh'))")
        if first["ok"]:
            break
        assert "in the past" in first["error"], first
    assert first["ok"] and first["answer"].startswith("ok: sot.remove('taskrh') at t ="), first
    second = live.client.command(f"attime({t + ahead:.3f}, sot.up('taskrh'))")  # refused at T: removed by then
    if second["ok"]:
        stack = live.ask("sot.stack()")
        if float(live.ask("time()")) < t + ahead:  # (the stack was read before T: on a loaded machine T may be past)
            assert "taskrh" in stack
    else:  # (a loaded machine: T passed between the two commands, and the second is refused as past)
        assert "in the past" in second["error"] and float(live.ask("time()")) >= t + ahead, second
    live.wait_until(t + ahead + 0.1)
    assert "taskrh" not in live.ask("sot.stack()")
    assert live.status()["attime_refused"] == refused + second["ok"]
    assert not live.client.command(f"attime({t - 1:.3f}, sot.pop())")["ok"]  # the past


@pytest.mark.skipif(shutil.which("chromium") is None, reason="chromium is not installed (apt-get install chromium)")
def test_headless_chromium_shows_talos(live, tmp_path):
    import matplotlib.image

    from tests.chromium import screenshot_until

    def dark_share(picture) -> float:
        pixels = matplotlib.image.imread(picture)[..., :3]
        view = pixels[30:-100, :-20]  # below Meshcat's control bar, above the scroll bar
        return float((view.max(axis=2) < 50 / 255).mean())  # TALOS' black covers; the background is light grey

    url = json.loads((live.out / "live.json").read_text())["meshcat"]
    picture, shown = screenshot_until(url, tmp_path / "meshcat.png", lambda p: dark_share(p) > 0.005)
    assert shown, f"{dark_share(picture):.4f} of the view is dark: no robot in {picture}"


def test_ctrl_c_stops_and_writes_the_run(live):
    live.process.send_signal(signal.SIGINT)
    assert live.process.wait(START_S) == 0, live.log.read_text()
    summary = json.loads((live.out / "summary.json").read_text())
    assert summary["final_stack"] == ["taskcontactRF", "taskcontactLF", "taskcom"]
    assert summary["live"]["accepted"] > BURST / 4 and summary["live"]["rejected"] > BURST / 2
    trace = np.load(live.out / "trace.npz")
    assert trace["q"].shape[0] == summary["ticks"] == summary["live"]["ticks"] + 1  # and q at t = 0
    assert not (live.out / "live.json").exists()
    assert "stopped at t = " in live.log.read_text()


def test_any_script_runs_live(tmp_path):
    """``python -m sotdrake.live <script>``: a script that only exposes ``build_diagram`` (and
    ``summarize``) runs live; ``stop()`` ends it, and it writes its files."""
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(ROOT), XDG_RUNTIME_DIR=str(tmp_path))
    with open(tmp_path / "log", "w") as log:
        process = subprocess.Popen(
            [sys.executable, "-m", "sotdrake.live", str(ROOT / "diagrams" / "kinesimple.py"), "--out", str(out),
             "--no-meshcat"], cwd=tmp_path, env=env, stdout=log, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + START_S
        while not (tmp_path / "sotdrake" / "live.json").exists():
            assert process.poll() is None and time.monotonic() < deadline, (tmp_path / "log").read_text()
            time.sleep(0.1)
        default = tmp_path / "sotdrake" / "live.json"  # the shell's default: the latest run of this user
        result = subprocess.run([sys.executable, "-m", "sotdrake.live.shell", "--timeout", str(ANSWER_S), "sot.stack()",
                                 "stop()"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=START_S)
        assert result.returncode == 0, result.stderr
        assert result.stdout.split("\n")[:2] == ["['tasklw']", "ok: stopping"]
        assert process.wait(START_S) == 0
    finally:
        process.kill()
    text = (tmp_path / "log").read_text()
    assert "commands: sotdrake-shell --connection" in text and "meshcat:" not in text
    summary = json.loads((out / "summary.json").read_text())
    assert summary["live"]["ticks"] > 0 and summary["live"]["accepted"] == 2
    assert (out / "trace.npz").is_file() and not (out / "live.json").exists() and not default.exists()


def test_the_shell_is_an_entry_point():
    import tomllib

    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["sotdrake-shell"] == "sotdrake.live.shell:main"
    from sotdrake.live.shell import main

    assert main(["--connection", "/nonexistent/live.json", "sot.stack()"]) == 2
