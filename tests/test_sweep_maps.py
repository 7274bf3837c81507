"""The sweep scripts: reach_map (SolverKine reach targets) and push_map (pushes on the physics stand)."""

import importlib
import json

import numpy as np
import pytest

from sotdrake import tilt_of_quaternions
from sotdrake.exceptions import InvalidInput
from sotdrake.sweep import read_csv, run_sweep


@pytest.fixture(scope="module")
def reach_map():
    return importlib.import_module("sotdrake.scenarios.reach_map")


@pytest.fixture(scope="module")
def push_map():
    from sotdrake.scenarios import push_map as module

    return module


def test_reach_targets_fill_the_box(reach_map):
    cases = reach_map.targets(27)
    xyz = np.array([[c["x"], c["y"], c["z"]] for c in cases])
    assert len(np.unique(xyz, axis=0)) == 27
    for k, axis in enumerate("xyz"):
        assert sorted(np.unique(xyz[:, k])) == pytest.approx(np.linspace(*reach_map.BOX[axis], 3))
    assert reach_map.targets(5, "random", seed=3) == reach_map.targets(5, "random", seed=3)
    with pytest.raises(InvalidInput, match="cube"):
        reach_map.targets(10)


def test_reachable_target_is_reached_with_feet_and_com_held(reach_map):
    summary = reach_map.reach_case({"x": 0.5, "y": -0.2, "z": 1.0}, duration=1.0, dt=0.02)
    # 0.41 m away, gain 8 /s: e^{-8} 0.41 m ≈ 1.4e-4 m after 1 s if nothing saturates.
    assert summary["hand_initial_error_m"] == pytest.approx(0.414, abs=1e-3)
    assert summary["reached"] and summary["hand_error_m"] < 1e-3
    assert summary["max_foot_drift_m"] < 1e-3 and summary["max_com_drift_m"] < 1e-3
    assert summary["min_joint_limit_margin_rad"] > 0


def test_reach_map_script_writes_the_table_and_holds_the_limits(reach_map, tmp_path):
    summary = reach_map.main(["--targets", "8", "--duration", "0.4", "--out", str(tmp_path), "--quiet"])
    for name in ("reach_map.csv", "reach_map.json", "plots.png", "summary.json", "control_graph.dot"):
        assert (tmp_path / name).is_file(), name
    rows = read_csv(tmp_path / "reach_map.csv")
    assert [int(r["case"]) for r in rows] == list(range(8)) and {r["status"] for r in rows} == {"ok"}
    # The box's corners are out of reach: the hand stops short, every joint stays within its
    # limits (the QP's position margin is 1e-3 rad; allow rounding).
    assert all(float(r["hand_error_m"]) > 0.1 for r in rows)
    assert min(float(r["min_joint_limit_margin_rad"]) for r in rows) > 1e-3 - 1e-9
    assert summary["reached_within_1cm"] == 0 and summary["errors"] == 0
    assert json.loads((tmp_path / "reach_map.json").read_text())["settings"]["ticks_per_case"] == 20


def test_push_direction_and_base_tilt(push_map):
    assert push_map.push_force(200.0, 90.0) == pytest.approx([0.0, 200.0, 0.0], abs=1e-12)
    half = np.sqrt(0.5)  # base turned by 40° about x, then by 90° about z (which keeps the tilt)
    q = np.array([[1, 0, 0, 0], [np.cos(np.radians(20)), np.sin(np.radians(20)), 0, 0],
                  [np.cos(np.radians(20)) * half, np.sin(np.radians(20)) * half, np.sin(np.radians(20)) * half,
                   np.cos(np.radians(20)) * half]])
    assert tilt_of_quaternions(q) == pytest.approx([0, 40, 40], abs=1e-9)


@pytest.mark.slow
def test_gentle_push_absorbed_strong_push_falls(push_map):
    cases = [{"magnitude_n": 50.0, "direction_deg": 0.0, "push_duration_s": 0.05},
             {"magnitude_n": 600.0, "direction_deg": 0.0, "push_duration_s": 0.2},
             {"magnitude_n": -1.0, "direction_deg": 0.0, "push_duration_s": 0.2}]
    result = run_sweep(lambda case: push_map.push_case(case, duration=0.6, push_start=0.1), cases, progress=False)
    gentle, strong, bad = result.rows
    assert not gentle["fell"] and gentle["base_height_drop_m"] < 0.01 and gentle["base_drift_m"] < 0.02
    assert gentle["max_base_tilt_deg"] < 2
    # 120 N s on 90 kg: about 1.3 m/s, far more than standing feet can take.
    assert strong["fell"] and strong["base_drift_m"] > 0.2
    assert bad["status"] == "error" and "magnitude_n" in bad["error"]
