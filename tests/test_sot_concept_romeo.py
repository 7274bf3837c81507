"""sot-concept's configurations 0–7 on Romeo, the original's robot (sot-romeo's ``small`` model,
``SolverKine``, 5 ms ticks), each judged by its lesson from the script's summary."""

from __future__ import annotations

import dataclasses

import pytest

from sotdrake.scenarios import sot_concept as sot_concept_scenario


@pytest.fixture(scope="module")
def concept():
    return sot_concept_scenario


def run(concept, name, **changes):
    config = dataclasses.replace(concept.CONFIGURATIONS[name], **changes)
    handles = concept.build_diagram(config, robot_name="romeo")
    simulator, wall = concept.run(handles, progress=False)
    return concept.summarize(handles, simulator, wall)[0]


@pytest.fixture(scope="module")
def summaries(concept):
    return {name: run(concept, name, duration=2.5) for name in ("seed0", "seed1", "seed2", "seed3", "seed4", "seed5")}


def test_the_robot_and_the_stacks_are_the_originals(summaries):
    feet = ["taskcontactRF", "taskcontactLF"]
    assert {s["robot"] for s in summaries.values()} == {"romeo"}
    assert summaries["seed0"]["stack"] == ["taskrh"]
    assert summaries["seed2"]["stack"] == ["taskrh", *feet]
    assert summaries["seed4"]["stack"] == ["taskrh", "taskJL", *feet, "taskcom"]
    assert summaries["seed5"]["stack"] == ["taskrh", *feet, "tasksupport"]


def test_hand_only_drags_the_whole_body(summaries):
    s = summaries["seed0"]
    assert s["hand_error_m"] < 1e-2 and s["max_foot_drift_m"] > 0.05 and not s["balance_kept"]


def test_feet_below_the_hand_balance_kept_then_lost(summaries):
    kept, lost = summaries["seed1"], summaries["seed2"]
    for s in (kept, lost):
        assert s["hand_error_m"] < 1e-2 and s["max_foot_drift_m"] < 1e-4
    assert kept["balance_kept"] and kept["min_com_support_margin_m"] > 0.01
    # the ball behind and above pulls the CoM out of the soles on the way (then back, just inside)
    assert not lost["balance_kept"] and lost["min_com_support_margin_m"] < -0.003
    assert lost["max_com_box_excess_m"] > 0.01  # and out of the seed's support box


def test_com_held_and_the_shoulder_stops_at_its_artificial_limit(summaries):
    free, limited = summaries["seed3"], summaries["seed4"]
    for s in (free, limited):
        assert s["hand_error_m"] < 1e-2 and s["com_error_m"] < 1e-4 and s["balance_kept"]
    assert free["limited_joint_max_rad"] > 0.2  # the reach turns the right shoulder yaw past 0
    assert limited["limited_joint_max_rad"] <= 1e-4 and limited["limited_joint_final_rad"] > -1e-2  # held at 0


def test_com_inside_the_support_box(summaries):
    s = summaries["seed5"]
    assert s["max_com_box_excess_m"] <= 1e-4 and s["balance_kept"] and s["hand_error_m"] < 1e-2


@pytest.mark.slow
def test_singular_approach_after_the_originals_four_steps(concept):
    """The original's four +0.1 m steps take Romeo's arm to its reach: with the hand first the
    levels below it ask for a joint's velocity limit; with the feet above the hand and damping 0.1
    on the last level they stay below it. The feet hold in both."""
    undamped, damped = run(concept, "seed6"), run(concept, "seed7")
    assert undamped["max_joint_velocity_ratio"] > 0.99
    assert damped["max_joint_velocity_ratio"] < 0.9
    for s in (undamped, damped):
        assert s["max_foot_drift_m"] < 1e-4 and s["hand_error_m"] < 2e-3
    assert damped["stack"] == ["taskcontactRF", "taskcontactLF", "taskrh", "taskcom"]


def test_extras_are_talos_only(concept, tmp_path):
    with pytest.raises(SystemExit):
        concept.main(["--robot", "romeo", "--config", "extra", "--out", str(tmp_path), "--no-meshcat", "--quiet"])


def test_unknown_robot_is_refused(concept):
    with pytest.raises(concept.SotError, match="robot_name"):
        concept.build_diagram(concept.CONFIGURATIONS["seed0"], robot_name="nao")
