"""Short runs of the catalog robots' scripts: kineromeo (Romeo) and pr2_reach (PR2)."""

import json

import numpy as np
import pytest

from sotdrake.scenarios import planche as planche_scenario

OUTPUTS = ("trace.npz", "plots.png", "control_graph.dot", "summary.json")


@pytest.fixture(scope="module")
def kineromeo():
    from sotdrake.scenarios import kineromeo as module

    return module


@pytest.fixture(scope="module")
def pr2_reach():
    from sotdrake.scenarios import pr2_reach as module

    return module


def test_kineromeo_hand_closes_in_with_feet_and_com_held(kineromeo, tmp_path):
    summary = kineromeo.main(["--duration", "1.0", "--out", str(tmp_path), "--quiet", "--no-meshcat"])
    for name in OUTPUTS:
        assert (tmp_path / name).is_file(), name
    assert json.loads((tmp_path / "summary.json").read_text())["ticks"] == summary["ticks"] == 201
    assert (summary["robot"], summary["variant"]) == ("romeo", "small")
    assert summary["final_stack"] == ["taskcontactRF", "taskcontactLF", "taskcom", "taskrh"]
    # The seed's target is 0.33 m from Romeo's hand. Solved exactly, the hand task decays at least
    # at the setByPoint gain's floor λ∞ = 0.9 /s (λ(e) = 4 e^{-10.54 |e|} + 0.9).
    assert summary["hand_initial_error_m"] == pytest.approx(0.328, abs=1e-3)
    assert summary["hand_error_m"] < summary["hand_initial_error_m"] * np.exp(-0.9 * 1.0)
    assert summary["max_foot_drift_m"] < 1e-4 and summary["max_com_xy_drift_m"] < 1e-4
    trace = np.load(tmp_path / "trace.npz")
    assert trace["q"].shape == (201, 38)
    hand_error = np.linalg.norm(trace["hand_position"] - summary["target_m"], axis=1)
    assert np.all(np.diff(hand_error) <= 1e-12)  # monotonic
    graph = (tmp_path / "control_graph.dot").read_text()
    for entity in ("solver", "joint_limitator", "device", "dynamic", "taskrh", "taskcom", "taskcontactLF"):
        assert entity in graph
    assert summary["joint_limitator"] and summary["min_joint_limit_margin_rad"] >= 0.0


def test_kineromeo_joint_limitator_keeps_g1_knees_within_their_limits(kineromeo, tmp_path):
    """G1's knees reach full extension (their lower limit) 0.47 s into the reach: the bare SOT
    takes them past it, the seed's Solver(robot) stops them there."""
    args = ["--robot", "g1", "--duration", "0.7", "--quiet", "--no-meshcat"]
    bare = kineromeo.main([*args, "--no-limitator", "--out", str(tmp_path / "bare")])
    assert not bare["joint_limitator"] and bare["min_joint_limit_margin_rad"] < 0.0
    wrapped = kineromeo.main([*args, "--out", str(tmp_path / "wrapped")])
    assert wrapped["joint_limitator"] and wrapped["min_joint_limit_margin_rad"] >= 0.0


def test_pr2_reach_moves_the_base_and_the_arm_within_limits(pr2_reach, tmp_path):
    summary = pr2_reach.main(["--duration", "0.25", "--out", str(tmp_path), "--quiet", "--no-meshcat"])
    for name in OUTPUTS:
        assert (tmp_path / name).is_file(), name
    assert summary["solver"] == "SolverKine" and summary["base"] == "planar"
    assert summary["ticks"] == 251
    assert summary["base_travel_m"] > 0.05  # the base drives toward the table
    assert summary["hand_error_m"] < summary["hand_initial_error_m"] - 0.1
    assert summary["min_joint_limit_margin_rad"] >= -1e-9  # hard limits (the torso starts on its lower one)
    assert summary["max_joint_velocity_ratio"] <= 1 + 1e-9
    assert summary["max_base_yaw_rad"] < 1e-6
    trace = np.load(tmp_path / "trace.npz")
    # Only the base, the torso and the right arm move.
    handles = pr2_reach.build_diagram()
    plant = handles.robot.model.plant
    moved = set(pr2_reach.controlled_joints(handles.robot))
    q = trace["q"]
    for j in plant.GetJointIndices():
        joint = plant.get_joint(j)
        if joint.num_positions() and joint.name() not in moved:
            start = joint.position_start()
            assert np.ptp(q[:, start : start + joint.num_positions()]) == 0.0, joint.name()


@pytest.fixture(scope="module")
def dynromeo():
    from sotdrake.scenarios import dynromeo as module

    return module


@pytest.fixture(scope="module")
def planche():
    return planche_scenario


def test_dynromeo_com_goes_over_the_left_sole_with_both_soles_held(dynromeo, tmp_path):
    summary = dynromeo.main(["--duration", "1.2", "--out", str(tmp_path), "--quiet", "--no-meshcat"])
    for name in OUTPUTS:
        assert (tmp_path / name).is_file(), name
    assert (summary["robot"], summary["device"], summary["com_task"]) == ("romeo", "RobotDynSimu", True)
    assert summary["ticks"] == 240 and not summary["fell"]
    assert summary["max_left_sole_move_m"] < 1e-3 and summary["max_left_sole_tilt_rad"] < 1e-3  # held (no position feedback)
    assert summary["com_rms_error_m"] < 1e-3  # the CoM follows its minimum-jerk reference
    assert summary["max_torque_ratio"] <= 1 + 1e-9  # torque limits are hard bounds
    trace = np.load(tmp_path / "trace.npz")
    forces = trace["wrenches"][:, [5, 11]]
    assert np.allclose(forces.sum(axis=1), forces[0].sum(), rtol=0.05)  # the weight, shared
    assert forces[-1, 0] > 1.5 * forces[-1, 1]  # shifted onto the left sole
    graph = (tmp_path / "control_graph.dot").read_text()
    for entity in ("sot", "device", "dynamic", "contactLF", "contactRF", "taskcom", "taskRF"):
        assert entity in graph


def test_dynromeo_without_the_com_task_romeo_falls(dynromeo, tmp_path):
    """The seed's "what happens?": the right contact removed with the CoM between the feet."""
    summary = dynromeo.main(["--scenario", "lift_leg_no_com", "--duration", "3.0", "--out", str(tmp_path), "--quiet",
                             "--no-meshcat"])
    assert not summary["com_task"] and summary["fell"]
    assert dynromeo.RELEASE[0] < summary["fell_at_s"] < 3.0
    assert summary["com_margin_in_left_sole_at_release_m"] < -0.03  # the CoM outside the left sole
    assert summary["right_force_at_release_n"] > 150  # the right sole carried half the weight
    assert summary["com_shift_at_end_m"][1] < -0.1  # tipping over towards the right
    assert summary["what_happens"].startswith("Romeo falls")


def test_planche_com_inside_the_shrunken_support_before_the_foot_leaves(planche, tmp_path):
    summary = planche.main(["--duration", "2.0", "--out", str(tmp_path), "--quiet", "--no-meshcat"])
    for name in OUTPUTS:
        assert (tmp_path / name).is_file(), name
    assert summary["solver"] == "SolverKine" and summary["ticks"] == 401
    assert summary["final_contacts"] == ["taskcontactLF"] and summary["final_stack"] == ["taskcom", "taskrf", "taskrest"]
    assert summary["com_in_shrunken_support_from_s"] < planche.T["lift"]
    assert summary["min_com_margin_single_support_m"] >= -1e-5  # the inequality holds on one foot
    assert summary["max_left_ankle_drift_m"] < 1e-4
    assert summary["max_right_ankle_height_m"] > 0.2  # the right foot goes up
    assert summary["min_joint_limit_margin_rad"] >= 0.0
    trace = np.load(tmp_path / "trace.npz")
    lifted = trace["time"] >= planche.T["lift"]
    assert np.all(trace["com_margin"][lifted] >= -1e-5)


@pytest.mark.slow
def test_planche_full_variant_extends_arms_foot_and_head_the_reduced_does_not(planche, tmp_path):
    """The seed's WITH_FULL_EXTENTION: after the arms (7.05 s) and the foot and head (11.2 s) steps,
    the shoulders' yaws, the right ankle's pitch and the neck's pitch have gone toward their
    targets (∓π/2, 0.73, −π/4), each as far as its joint limit lets it; the reduced variant keeps
    them near half-sitting. The CoM stays over the shrunken support on one foot in both."""
    end = planche.FULL["foot"] + 1.0
    args = ["--duration", str(end), "--quiet", "--no-meshcat"]
    full = planche.main([*args, "--out", str(tmp_path / "full")])
    reduced = planche.main([*args, "--variant", "reduced", "--out", str(tmp_path / "reduced")])
    assert (full["planche_variant"], reduced["planche_variant"]) == ("full", "reduced")
    assert full["min_right_shoulder_yaw_rad"] < -1.1 and reduced["min_right_shoulder_yaw_rad"] > -0.7  # half-sitting: −0.6
    assert full["max_right_ankle_pitch_rad"] > 0.6 and reduced["max_right_ankle_pitch_rad"] < 0.1
    assert full["min_neck_pitch_rad"] < -0.3 and reduced["min_neck_pitch_rad"] > -0.1
    for summary in (full, reduced):
        assert summary["min_com_margin_single_support_m"] >= -1e-5 and summary["min_joint_limit_margin_rad"] >= 0.0
