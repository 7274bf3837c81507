"""Scripts refuse what they would not do, before they run, and write strict JSON: the README media
script's ``--out`` and options, ``summary.json`` when no pair came in range, and ``talos_appli``'s
options of a live run."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parents[1]


def strict_json(path: Path) -> object:
    """``path``'s JSON, refusing ``Infinity`` and ``NaN`` (not JSON, though Python writes them)."""
    def refuse(constant: str) -> object:
        raise ValueError(f"{path.name}: {constant} is not JSON")

    return json.loads(path.read_text(), parse_constant=refuse)


@pytest.mark.parametrize(("options", "named"), [
    ([], "--out {out}: cannot create the output directory"),
    (["--no-meshcat"], "unrecognized arguments: --no-meshcat"),  # (the hero image needs Meshcat: no such option)
])
def test_make_readme_media_refuses_before_it_runs(tmp_path, options, named):
    """The script lives in diagrams/ only: run as a user runs it."""
    out = tmp_path / "a_file"
    out.write_text("not a folder")
    run = subprocess.run([sys.executable, str(ROOT / "diagrams" / "make_readme_media.py"), "--out", str(out), "--quiet",
                          "--no-physics", *options], cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 2, run.stderr
    assert f"make_readme_media.py: error: {named.format(out=out)}" in run.stderr and "Traceback" not in run.stderr
    assert out.read_text() == "not a folder"


def built() -> SimpleNamespace:
    """What the scenarios' ``summary.json`` needs of a built run: a diagram, no visualizer."""
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    builder = DiagramBuilder()
    builder.AddSystem(ConstantVectorSource([0.0]))
    return SimpleNamespace(diagram=builder.Build(), visualizer=None)


def test_pr2_shelf_writes_no_pair_in_range_as_null(tmp_path, monkeypatch):
    from sotdrake.scenarios import pr2_shelf

    monkeypatch.setattr(pr2_shelf, "build_diagram", lambda **k: built())
    monkeypatch.setattr(pr2_shelf, "run", lambda reach, target, duration: {
        "min_signed_distance_m": math.inf, "hand_error_m": 0.2, "reached": False})
    summary = pr2_shelf.main(["--duration", "0.002", "--out", str(tmp_path), "--quiet", "--no-meshcat"])
    written = strict_json(tmp_path / "summary.json")
    assert summary["runs"]["low"]["with"]["min_signed_distance_m"] == math.inf
    assert written["runs"]["low"]["with"]["min_signed_distance_m"] is None
    assert written["runs"]["low"]["with"]["hand_error_m"] == 0.2


def test_talos_collisions_writes_no_pair_in_range_as_null(tmp_path, monkeypatch):
    from sotdrake.scenarios import talos_collisions

    report = SimpleNamespace(min_distance=math.inf, hand_error=0.1, feet_drift=0.0, failures=[])
    monkeypatch.setattr(talos_collisions, "build_collision_reach", lambda **k: built())
    monkeypatch.setattr(talos_collisions, "run_collision_reach", lambda *a, **k: report)
    talos_collisions.main(["--duration", "0.002", "--out", str(tmp_path), "--quiet", "--no-meshcat"])
    written = strict_json(tmp_path / "summary.json")
    assert {run["with"]["min_signed_distance_m"] for run in written["runs"].values()} == {None}


@pytest.mark.parametrize(("options", "named"), [
    (["--rate", "2"], "--rate: options of --live or --ros"),
    (["--rate", "nan"], "--rate: options of --live or --ros"),
    (["--port", "7100", "--meshcat-port", "7200"], "--port, --meshcat-port: options of --live or --ros"),
    (["--live", "--meshcat-port", "7200"], "--meshcat-port: an option of a live run with Meshcat"),
    (["--live", "--bag"], "--bag: a --live run writes no bag"),
])
def test_talos_appli_refuses_the_options_its_run_would_not_read(tmp_path, capsys, monkeypatch, options, named):
    from sotdrake.scenarios import talos_appli

    monkeypatch.setattr(talos_appli, "build_diagram", lambda *a, **k: pytest.fail("built"))
    with pytest.raises(SystemExit) as stopped:
        talos_appli.main([*options, "--out", str(tmp_path / "run"), "--no-meshcat", "--quiet", "--duration", "0.05"])
    assert stopped.value.code == 2 and f"error: {named}" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
