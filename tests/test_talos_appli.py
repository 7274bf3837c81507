"""The tutorial diagram: a short run, and the script's outputs."""

import base64
import json
import re

import numpy as np
import pytest


@pytest.fixture(scope="module")
def appli():
    from sotdrake.scenarios import talos_appli as module

    return module


@pytest.mark.slow
def test_tutorial_reaches_with_feet_and_com_held(appli):
    handles = appli.build_diagram()
    simulator, wall = appli.simulate(handles, 3.5, progress=False)
    summary, trace = appli.summarize(handles, simulator, 3.5, wall)
    assert summary["final_stack"] == ["taskcontactRF", "taskcontactLF", "taskcom", "taskrh"]
    assert summary["hand_initial_error_m"] == pytest.approx(0.414, abs=1e-3)
    assert summary["hand_error_m"] < 5e-3
    assert summary["max_foot_drift_m"] < 1e-4 and summary["max_com_drift_m"] < 1e-4
    assert summary["max_foot_rotation_drift_rad"] < 1e-4
    assert summary["min_joint_limit_margin_rad"] >= 0.0
    assert summary["ticks"] == len(trace["time"]) == 3501
    before = trace["time"] < 1.0  # nothing moves before the hand is pushed
    assert np.ptp(trace["q"][before], axis=0).max() < 1e-12
    hand_error = np.linalg.norm(trace["hand_position"] - handles.target, axis=1)
    assert np.all(np.diff(hand_error[~before]) <= 1e-12)  # monotonic convergence


def test_script_writes_its_outputs(appli, tmp_path):
    summary = appli.main(["--duration", "0.3", "--out", str(tmp_path), "--quiet"])
    for name in ("trace.npz", "plots.png", "control_graph.dot", "summary.json", "recording.html"):
        assert (tmp_path / name).is_file(), name
    saved = json.loads((tmp_path / "summary.json").read_text())
    for key in ("hand_error_m", "max_foot_drift_m", "max_com_drift_m", "ticks", "wall_s", "realtime_factor"):
        assert key in saved
    assert saved["ticks"] == summary["ticks"] == 301
    graph = (tmp_path / "control_graph.dot").read_text()
    for entity in ("sot", "device", "dynamic", "taskrh", "featurerh", "featurerh_ref", "gainrh"):
        assert entity in graph
    html = (tmp_path / "recording.html").read_text()
    commands = b"".join(base64.b64decode(blob) for blob in re.findall(r"base64,([A-Za-z0-9+/=]+)", html))
    assert b"/target" in commands and b"arm_right_7_link" in commands  # the marker and TALOS' meshes
    assert commands.count(b"_meshfile_geometry") > 30
    trace = np.load(tmp_path / "trace.npz")
    assert trace["q"].shape == (301, 39)
