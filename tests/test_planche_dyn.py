"""planche.py --solver dyn: the seed's planche on RobotDynSimu + SolverDyn. It does not hold on
Romeo's model: the summary reports the fall (when, why, in which step), and these tests check that
what it reports is what the trace shows."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sotdrake.scenarios import planche as planche_scenario

SUPPORT_LEG = {"LHipYaw", "LHipRoll", "LHipPitch", "LKneePitch", "LAnklePitch", "LAnkleRoll"}


@pytest.fixture(scope="module")
def planche():
    return planche_scenario


def run(planche, options=None, variant="full", duration=21.0):
    dyn = planche.dynamic()
    handles = planche.build_dynamic(variant, options)
    simulator, cpu = dyn.simulate(handles, duration, progress=False)
    return (*dyn.summarize(handles, simulator, duration, cpu), handles)


@pytest.fixture(scope="module")
def default(planche):
    return run(planche)


def test_the_fall_is_reported_with_its_step(default, planche):
    summary, trace, handles = default
    dyn, T = planche.dynamic(), handles.times
    assert summary["solver"] == "SolverDyn" and summary["device"] == "RobotDynSimu"
    assert summary["fell"] and not summary["holds"]
    assert summary["fall_reason"] in ("sole moved", "sole tilted", "CoM dropped", "non-finite")
    assert T["lift"] + dyn.RELEASE_RAMP <= summary["fell_at_s"] < T["chest"]
    assert summary["fall_phase"] == dyn.phase_at(T, summary["fell_at_s"]) and summary["fall_phase"] in ("lift", "extend")
    assert summary["what_happens"].startswith("Romeo falls at t = ")
    # the trace agrees with the reason: at the fall the left sole has moved 1 cm (or the CoM dropped)
    k = int(np.searchsorted(trace["time"], summary["fell_at_s"]))
    if summary["fall_reason"] == "sole moved":
        assert trace["left_sole_move"][k] > dyn.FALL_SOLE_M > trace["left_sole_move"][k - 1]
    # the run stopped once the CoM had dropped (no ground under RobotDynSimu)
    assert summary["com_drop_m"] > 0.25 and trace["time"][-1] < summary["fell_at_s"] + 2.0
    # the pelvis leans with the planche: the shared 30° tilt criterion fires first, and is reported
    assert summary["fall_report"]["fell"] and summary["fall_report"]["fell_at_s"] <= summary["fell_at_s"]


def test_until_the_fall_the_com_holds_and_the_leg_rises(default):
    """Finite, the CoM inside the left support the whole time on one foot, the right ankle up to
    the seed's 0.65 m: the fall is not a CoM failure; the support leg is at its torque limits."""
    summary, trace, _ = default
    before = trace["time"] < summary["fell_at_s"]
    assert np.all(np.isfinite(trace["x"][before]))
    assert summary["min_com_margin_in_support_single_m"] > 0.02
    assert summary["max_right_ankle_height_before_fall_m"] > 0.65 and summary["time_on_one_foot_s"] > 1.0
    assert SUPPORT_LEG & set(summary["joints_at_torque_limit_before_fall"])


@pytest.mark.slow
def test_the_seeds_shrunken_support_falls_sooner(planche, default):
    dyn = planche.dynamic()
    seed = dataclasses.replace(dyn.DynOptions(), com_rise=0.0, shrink=True)
    summary, _, _ = run(planche, seed)
    assert summary["support_rectangle_m"][1] - summary["support_rectangle_m"][0] == pytest.approx(0.06)
    assert summary["fell"] and summary["fall_phase"] == "lift"
    assert summary["fell_at_s"] < default[0]["fell_at_s"]
    assert summary["max_right_ankle_height_before_fall_m"] < 0.5 * default[0]["max_right_ankle_height_before_fall_m"]


@pytest.mark.slow
def test_a_stronger_romeo_stays_up_longer(planche, default):
    """The diagnostic: three times the model's torque limits keep Romeo on its foot past the chest's lean."""
    dyn = planche.dynamic()
    summary, _, handles = run(planche, dataclasses.replace(dyn.DynOptions(), effort=3.0))
    assert not summary["fell"] or summary["fell_at_s"] > handles.times["body"]
    assert summary["max_torque_ratio_before_fall"] <= 1.0 + 1e-9


def test_bad_options_are_refused(planche, tmp_path):
    for flag in ("--slow", "--effort"):
        with pytest.raises(SystemExit):
            planche.main(["--solver", "dyn", flag, "0", "--out", str(tmp_path), "--no-meshcat", "--quiet"])
        with pytest.raises(SystemExit):  # an option of --solver dyn alone, not silently ignored
            planche.main([flag, "2", "--out", str(tmp_path), "--no-meshcat", "--quiet"])
    assert not any(tmp_path.iterdir())
    with pytest.raises(planche.dynamic().SotError, match="slow"):
        planche.build_dynamic("full", dataclasses.replace(planche.dynamic().DynOptions(), slow=-1.0))
