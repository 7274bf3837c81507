"""sot-concept's configurations 0–7 as the original built them (on TALOS), each judged by its
lesson from the script's summary."""

from __future__ import annotations

import dataclasses

import pytest

from sotdrake.scenarios import sot_concept as sot_concept_scenario


@pytest.fixture(scope="module")
def concept():
    return sot_concept_scenario


def run(concept, name, **changes):
    config = dataclasses.replace(concept.CONFIGURATIONS[name], **changes)
    handles = concept.build_diagram(config)
    simulator, wall = concept.run(handles, progress=False)
    return concept.summarize(handles, simulator, wall)[0]


@pytest.fixture(scope="module")
def summaries(concept):
    return {name: run(concept, name, duration=2.5) for name in ("seed0", "seed1", "seed2", "seed3", "seed4", "seed5")}


def test_the_stacks_are_the_originals(summaries):
    """The hand first; sot-dyninv's addContact puts the feet below it (keep() then push)."""
    feet = ["taskcontactRF", "taskcontactLF"]
    assert summaries["seed0"]["stack"] == ["taskrh"]
    assert summaries["seed1"]["stack"] == summaries["seed2"]["stack"] == ["taskrh", *feet]
    assert summaries["seed3"]["stack"] == ["taskrh", *feet, "taskcom"]
    assert summaries["seed4"]["stack"] == ["taskrh", "taskJL", *feet, "taskcom"]
    assert summaries["seed5"]["stack"] == ["taskrh", *feet, "tasksupport"]


def test_hand_only_drags_the_whole_body(summaries):
    s = summaries["seed0"]
    assert s["hand_error_m"] < 1e-2 and s["max_foot_drift_m"] > 0.05 and not s["balance_kept"]


def test_feet_below_the_hand_balance_kept_then_lost(summaries):
    kept, lost = summaries["seed1"], summaries["seed2"]
    for s in (kept, lost):
        assert s["hand_error_m"] < 1e-2 and s["max_foot_drift_m"] < 1e-4
    assert kept["balance_kept"] and kept["min_com_support_margin_m"] > 0
    assert not lost["balance_kept"] and lost["com_support_margin_m"] < -0.02  # the CoM has left the soles


def test_com_held_below_the_hand(summaries):
    s = summaries["seed3"]
    assert s["hand_error_m"] < 1e-2 and s["com_error_m"] < 1e-4 and s["balance_kept"]


def test_the_joint_stops_at_its_artificial_limit(summaries):
    free, limited = summaries["seed3"], summaries["seed4"]
    assert free["limited_joint_max_rad"] > 0.1  # the reach turns the torso past 0 without the limit
    assert limited["limited_joint_max_rad"] <= 1e-4 and limited["limited_joint_final_rad"] > -1e-2  # held at 0
    assert limited["hand_error_m"] < 1e-2


def test_com_kept_in_the_support_box(summaries):
    s = summaries["seed5"]
    assert s["max_com_box_excess_m"] <= 1e-4  # inside (−0.08..0.11, −0.15..0.15) to 1e-4 m
    assert s["com_box_excess_m"] > -1e-3  # on its edge: the hand pulls it there
    assert s["max_foot_drift_m"] < 1e-4


@pytest.mark.slow
def test_singular_approach_without_and_with_damping(concept):
    """Twelve +0.1 m steps take TALOS's arm past its reach: with the hand first, the levels below
    it ask for the joints' velocity limits and the feet slip; with the feet above the hand and
    damping 0.1 on the last level, the velocities stay below their limits and the feet hold."""
    times = concept.step_times(12)
    undamped = run(concept, "seed6", steps=times, duration=times[-1] + 1.0)
    damped = run(concept, "seed7", steps=times, duration=times[-1] + 1.0)
    assert undamped["max_joint_velocity_ratio"] > 0.99
    assert damped["max_joint_velocity_ratio"] < 0.8 and damped["max_foot_drift_m"] < 1e-4
    assert damped["stack"] == ["taskcontactRF", "taskcontactLF", "taskrh", "taskcom"]
