"""planche.py --solver dyn: the seed's planche on RobotDynSimu + SolverDyn. It does not hold on
Romeo's model: the summary reports the fall (when, why, in which step), and these tests check that
what it reports is what the trace shows."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tests.conftest import load_diagram


@pytest.fixture(scope="module")
def planche():
    return load_diagram("planche")


def run(planche, options=None, variant="full", duration=21.0):
    dyn = planche.dynamic()
    handles = planche.build_dynamic(variant, options)
    simulator, cpu = dyn.simulate(handles, duration, progress=False)
    return (*dyn.summarize(handles, simulator, duration, cpu), handles)


@pytest.fixture(scope="module")
def default(planche):
    return run(planche)


def test_the_fall_is_reported_in_the_lift(default, planche):
    summary, trace, handles = default
    T, ramp = handles.times, planche.dynamic().RELEASE_RAMP
    assert summary["solver"] == "SolverDyn" and summary["device"] == "RobotDynSimu"
    assert summary["fell"] and not summary["holds"] and summary["fall_reason"] in ("tilt", "sole moved", "sole tilted")
    assert T["lift"] + ramp <= summary["fell_at_s"] < T["extend"] and summary["fall_phase"] == "lift"
    assert summary["what_happens"].startswith("Romeo falls at t = ")
    # the run stopped after the fall, once the CoM had dropped (no ground under RobotDynSimu)
    assert summary["com_drop_m"] > 0.25 and trace["time"][-1] < T["extend"] + 1.0


def test_until_the_fall_the_contacts_and_the_com_hold(default):
    """Finite, the left sole held to 2 mm, the CoM inside the left support the whole time on one
    foot, the right foot lifted from its contact and tracking its reference: the fall is not a
    contact or CoM failure, the torque limits are what give."""
    summary, trace, _ = default
    before = trace["time"] < summary["fell_at_s"]
    assert np.all(np.isfinite(trace["x"][before]))
    assert summary["max_left_sole_move_before_fall_m"] < 2e-3
    assert summary["min_com_margin_in_support_single_m"] > 0.02
    assert 0.2 < summary["max_right_ankle_height_before_fall_m"] < 0.65
    assert summary["max_rf_tracking_error_before_fall_m"] < 0.1
    assert summary["max_torque_ratio_before_fall"] > 0.999 and summary["first_torque_limit_s"] < summary["fell_at_s"]
    support_leg = {"LHipYaw", "LHipRoll", "LHipPitch", "LKneePitch", "LAnklePitch", "LAnkleRoll"}
    assert support_leg & set(summary["joints_at_torque_limit_before_fall"])  # the support leg gives


@pytest.mark.slow
def test_the_seeds_shrunken_support_falls_as_the_foot_leaves(planche, default):
    dyn = planche.dynamic()
    seed = dataclasses.replace(dyn.DynOptions(), rf_kp=100.0, com_rise=0.0, shrink=True)
    summary, _, handles = run(planche, seed)
    assert summary["support_rectangle_m"][1] - summary["support_rectangle_m"][0] == pytest.approx(0.06)
    assert summary["fell"] and summary["fall_phase"] == "lift"
    assert summary["fell_at_s"] < default[0]["fell_at_s"]
    assert summary["max_right_ankle_height_before_fall_m"] < default[0]["max_right_ankle_height_before_fall_m"]


def test_bad_options_are_refused(planche, tmp_path):
    with pytest.raises(SystemExit):
        planche.main(["--solver", "dyn", "--slow", "0", "--out", str(tmp_path), "--no-meshcat", "--quiet"])
    with pytest.raises(planche.dynamic().SotError, match="slow"):
        planche.build_dynamic("full", dataclasses.replace(planche.dynamic().DynOptions(), slow=-1.0))
