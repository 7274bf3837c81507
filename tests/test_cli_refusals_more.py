"""The scripts' refusals: one line ``<script>: error: <message>``, exit status 2, the ``--out``
folders made for the run removed if still empty (whichever check refused, whenever it ran), and the
options a mode does not read refused rather than ignored."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sotdrake import InvalidInput, run_script, script_arguments, start

ROOT = Path(__file__).resolve().parents[1]


def _run(main, capsys, monkeypatch, script: str = "walk.py") -> tuple[object, str]:
    """``run_script(main)`` as the script ``script``: its exit status and its stderr."""
    monkeypatch.setattr("sys.argv", [script])
    with pytest.raises(SystemExit) as stopped:
        run_script(main)
    return stopped.value.code, capsys.readouterr().err


def test_a_system_exit_with_a_message_is_one_line_and_status_2(tmp_path, capsys, monkeypatch):
    out = tmp_path / "new" / "run"

    def main():
        start(argparse.Namespace(duration=1.0, out=str(out), no_meshcat=True))
        raise SystemExit("--forces must be LOW,HIGH\nwith LOW < HIGH")

    code, err = _run(main, capsys, monkeypatch)
    assert code == 2 and err == "walk.py: error: --forces must be LOW,HIGH with LOW < HIGH\n"
    assert not (tmp_path / "new").exists()


def test_start_refusals_go_through_the_same_line(tmp_path, capsys, monkeypatch):
    def main():
        start(argparse.Namespace(duration=-1.0, out=str(tmp_path / "run"), no_meshcat=True))

    code, err = _run(main, capsys, monkeypatch, "kinesimple.py")
    assert code == 2 and err.startswith("kinesimple.py: error: --duration must be")
    blocker = tmp_path / "a_file"
    blocker.write_text("")

    def bad_out():
        start(argparse.Namespace(duration=1.0, out=str(blocker / "run"), no_meshcat=True))

    code, err = _run(bad_out, capsys, monkeypatch, "kinesimple.py")
    assert code == 2 and err.startswith("kinesimple.py: error: --out ")


def test_a_parser_error_after_start_removes_the_new_folders(tmp_path, capsys, monkeypatch):
    """``parser.error`` once ``start`` made ``--out`` (a check that needs the build, say)."""
    parser = script_arguments(__doc__, str(tmp_path / "unused"))
    parser.add_argument("--damping", type=float, default=1.0)

    def main():
        args = parser.parse_args(["--damping", "-1", "--out", str(tmp_path / "a" / "b"), "--no-meshcat"])
        start(args)
        assert (tmp_path / "a" / "b").is_dir()
        parser.error("--damping must be ≥ 0")

    code, err = _run(main, capsys, monkeypatch)
    assert code == 2 and err.strip().endswith("error: --damping must be ≥ 0")
    assert not (tmp_path / "a").exists()


def test_a_folder_made_without_start_is_removed_too_and_an_old_one_kept(tmp_path, capsys, monkeypatch):
    """A live run makes ``--out`` itself (its connection files), then refuses ``--rate 0``."""
    parser = script_arguments(__doc__, str(tmp_path / "unused"))
    existing = tmp_path / "existing"
    existing.mkdir()

    def main(out: Path):
        args = parser.parse_args(["--out", str(out)])
        args.out.mkdir(parents=True, exist_ok=True)
        raise InvalidInput("LiveRun: realtime_rate must be a number in [0.001, 1000], got 0.0")

    code, _ = _run(lambda: main(tmp_path / "new" / "run"), capsys, monkeypatch)
    assert code == 2 and not (tmp_path / "new").exists()
    code, _ = _run(lambda: main(existing), capsys, monkeypatch)
    assert code == 2 and existing.is_dir()


def test_push_momentum_refuses_before_it_runs(tmp_path):
    from sotdrake.scenarios import push_momentum

    for options, named in ((["--push-start", "5", "--duration", "0.1"], "--push-start"),
                           (["--push-start", "0.05", "--push-duration", "0.1", "--duration", "0.1"], "--push-duration"),
                           (["--forces", "100,20000"], "--forces"), (["--duration", "-1"], "--duration"),
                           (["--damping", "-1"], "--damping")):
        with pytest.raises(SystemExit, match=named):
            push_momentum.main([*options, "--out", str(tmp_path / "run"), "--quiet"])
    assert not (tmp_path / "run").exists()


def test_push_momentum_script_refusal_leaves_nothing(tmp_path):
    """The script as a user runs it: its error line last, status 2, no folder left."""
    out = tmp_path / "new" / "sub"
    done = subprocess.run([sys.executable, "diagrams/push_momentum.py", "--forces", "900,100", "--out", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 2 and done.stderr.strip().splitlines()[-1:] == [
        "push_momentum.py: error: --forces must be LOW,HIGH with 0 ≤ LOW < HIGH ≤ 10000 N and --steps ≥ 0, got (900.0, 100.0), 4"]
    assert not (tmp_path / "new").exists()


def test_target_switch_refuses_a_run_too_short_for_its_switch(tmp_path, capsys, monkeypatch):
    from sotdrake.scenarios import target_switch

    code, err = _run(lambda: target_switch.main(["--duration", "0.001", "--out", str(tmp_path / "run")]), capsys, monkeypatch,
                     "target_switch.py")
    assert code == 2 and err.startswith("target_switch.py: error: --duration must be at least")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(("options", "named"), [
    (["--step-duration", "0"], "--step-duration"),
    (["--single-support", "0"], "--single-support"),
    (["--steps", "0"], "--steps"),
])
def test_walk_refuses_zero_instead_of_taking_the_default(options, named, tmp_path, capsys):
    from sotdrake.scenarios import walk

    with pytest.raises(SystemExit) as stopped:
        walk.main([*options, "--out", str(tmp_path / "run"), "--no-meshcat", "--quiet", "--duration", "0.05"])
    assert stopped.value.code == 2 and f"error: {named}" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(("script", "options", "named"), [
    ("walk", ["--step-length", "0.1"], "--step-length: an option of --steps"),
    ("walk", ["--steps", "4", "--velocity", "0.1", "0", "0"], "--velocity: this run walks --steps"),
    ("sot_concept", ["--config", "seed0", "--steps", "12"], "--steps: an option of the configurations whose ball moves"),
])
def test_an_option_the_run_would_not_read_is_refused(script, options, named, tmp_path, capsys, monkeypatch):
    import importlib

    module = importlib.import_module(f"sotdrake.scenarios.{script}")
    monkeypatch.setattr(module, "build_diagram", lambda *a, **k: pytest.fail("built"))
    with pytest.raises(SystemExit) as stopped:
        module.main([*options, "--out", str(tmp_path / "run"), "--no-meshcat", "--quiet", "--duration", "0.05"])
    assert stopped.value.code == 2 and f"error: {named}" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(("options", "named"), [
    ({"then": (1.0, 0.1, 0.0, 0.0)}, "then"),
    ({"solver": "cascade"}, "solver"),
    ({"multibody_zmp": True}, "multibody_zmp"),
    ({"multibody_zmp": False}, "multibody_zmp"),
    ({"arms": "inequality"}, "arms"),
])
def test_the_dynamic_walk_refuses_what_it_does_not_read(options, named, monkeypatch):
    from sotdrake.walking import controller, dynamic_controller

    monkeypatch.setattr(dynamic_controller, "build_dynamic", lambda *a, **k: pytest.fail("built"))
    with pytest.raises(InvalidInput, match=named):
        controller.build_diagram("talos", steps=(2, 0.1), mode="dynamic", **options)


def test_talos_dynamics_names_the_contact_option_off_the_physics_device(tmp_path, capsys):
    from sotdrake.scenarios import talos_dynamics

    with pytest.raises(SystemExit) as stopped:
        talos_dynamics.main(["--device", "dynsimu", "--contact", "point", "--out", str(tmp_path / "run"), "--no-meshcat"])
    err = capsys.readouterr().err
    assert stopped.value.code == 2 and "error: --contact point" in err and "--device physics" in err
    assert not (tmp_path / "run").exists()


def test_simulate_refuses_what_is_not_a_visualizer_before_building(monkeypatch):
    from pydrake.geometry import Meshcat
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    import sotdrake.simulation
    from sotdrake import simulate

    builder = DiagramBuilder()
    builder.AddSystem(ConstantVectorSource(np.zeros(1)))
    diagram = builder.Build()
    monkeypatch.setattr(sotdrake.simulation, "Simulator", lambda *a: pytest.fail("the simulator was built"))
    with pytest.raises(InvalidInput, match=r"visualizer must be None or the MeshcatVisualizer.*str"):
        simulate(diagram, 0.1, "recording.html", progress=False)
    with pytest.raises(InvalidInput, match=r"visualizer.*got Meshcat: give add_robot_visualizer"):
        simulate(diagram, 0.1, Meshcat(), progress=False)


def test_help_shows_no_meaningless_default(capsys):
    from sotdrake.scenarios import kineromeo

    with pytest.raises(SystemExit):
        kineromeo.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "(no JointLimitator)" in text and "(default: True)" not in text and "(default: False)" not in text
    assert "(default: 5.0)" in text  # (a default that says something is kept)


@pytest.mark.parametrize("script", ["target_switch", "push_momentum"])
def test_scripts_without_a_recording_offer_no_no_meshcat(script, tmp_path):
    from importlib import import_module

    module = import_module(f"sotdrake.scenarios.{script}")
    with pytest.raises(SystemExit) as stopped:
        module.main(["--no-meshcat", "--out", str(tmp_path / "run")])
    assert stopped.value.code == 2 and not (tmp_path / "run").exists()


@pytest.mark.parametrize("timeout", ["0", "-1", "nan", "inf", "1e7"])
def test_ros_test_refuses_a_timeout_its_client_would_not_take(timeout):
    """Refused by the script's own line, before any ROS node is made (ROS 2 need not be installed)."""
    done = subprocess.run([sys.executable, "diagrams/ros_test.py", "--timeout", timeout],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 2 and "--timeout must be a number in (0, 1e6]" in done.stderr.strip().splitlines()[-1]
