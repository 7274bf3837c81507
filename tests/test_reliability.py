"""Reliability: the step limit, a refused timed command, the shared fall criterion, one robot per
builder, and the bad inputs of the reliability review (each a SotError, nothing changed)."""

import logging

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake.exceptions import InvalidInput, SotError
from sotdrake.fall import FALL_BASE_DROP_M, FALL_SLIP_M, FALL_TILT_DEG, fall_report, tilt_of_quaternions, tilt_of_rotations
from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, gotoNd
from sotdrake.robot import Robot, add_sot
from sotdrake.sequencer import attime
from sotdrake.solvers.step_limit import DEFAULT_STEP_LIMIT, clip_bounds
from tests.hostile import bad_inputs, run_attempts


# --- the step limit ----------------------------------------------------------------------------
def test_clip_bounds_keeps_the_bounds_ordered():
    lower, upper = clip_bounds(np.array([-5.0, 0.5, 3.0, -1.0]), np.array([5.0, 4.0, 6.0, -0.2]), 2.0)
    assert np.array_equal(lower, [-2.0, 0.5, 2.0, -1.0]) and np.array_equal(upper, [2.0, 2.0, 2.0, -0.2])
    assert np.all(lower <= upper)


def _reach(talos_model, solver: str, dt: float):
    """TALOS on its feet (contacts), the right hand sent 3 m away with a stiff gain."""
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model, dt)
    feet = [MetaTaskKine6d(n, robot, n[-2:], op) for n, op in (("contactRF", "right-ankle"), ("contactLF", "left-ankle"))]
    rh = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    sot = add_sot(robot, solver=solver)
    for foot in feet:
        foot.gain.setConstant(0.1 / dt)
        sot.addContact(foot)
    gotoNd(rh, (3.0, -1.0, 2.0), "111", 1.0 / dt)
    sot.push(rh.task.name)
    return builder.Build(), robot, sot


@pytest.mark.parametrize("solver", ["cascade", "hqp"])
@pytest.mark.parametrize("dt", [1e-3, 5e-3, 10e-3])
def test_each_tick_moves_at_most_the_step_and_the_feet_hold(talos_model, solver, dt):
    """Every component of the command within δ/dt (δ = 7e-3), and the ankles within 0.1 mm at
    every tick of an arm thrown at full speed, at 1, 5 and 10 ms."""
    diagram, robot, sot = _reach(talos_model, solver, dt)
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    own = sot.GetMyContextFromRoot(context)
    q0 = robot.device.position(context)
    start = {op: robot.dynamic.pose_at(op, q0).translation() for op in ("left-ankle", "right-ankle")}
    drift, fastest = 0.0, 0.0
    for k in range(1, 61):
        v = sot.GetOutputPort("control").Eval(own)
        fastest = max(fastest, float(np.abs(v).max()) * dt)
        simulator.AdvanceTo(k * dt)
        q = robot.device.position(context)
        drift = max(drift, *(float(np.linalg.norm(robot.dynamic.pose_at(op, q).translation() - p)) for op, p in start.items()))
    assert fastest <= DEFAULT_STEP_LIMIT * (1 + 1e-9)
    assert fastest > 0.5 * DEFAULT_STEP_LIMIT or dt == 1e-3  # the limit is reached at 5 and 10 ms
    assert drift <= 1e-4


def test_the_step_limit_is_a_setting(talos_model):
    diagram, robot, sot = _reach(talos_model, "hqp", 5e-3)
    context = diagram.CreateDefaultContext()
    sot.setStepLimit(np.inf, context)
    v = sot.GetOutputPort("control").Eval(sot.GetMyContextFromRoot(context))
    assert np.abs(v).max() * 5e-3 > DEFAULT_STEP_LIMIT  # without it the arm jumps to its velocity limits
    assert sot.settings(context).step_limit == np.inf and sot.settings().step_limit == DEFAULT_STEP_LIMIT
    for bad in (0.0, -1e-3, 2.0, np.nan, "0.01", None, True):
        with pytest.raises(InvalidInput, match="step limit"):
            sot.setStepLimit(bad, context)
    assert sot.settings(context).step_limit == np.inf


# --- a timed command refused at run time --------------------------------------------------------
@pytest.mark.parametrize("solver", ["cascade", "hqp"])
def test_a_refused_timed_command_leaves_the_run_going(talos_model, solver, caplog):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    lf = MetaTaskKine6d("contactLF", robot, "LF", "left-ankle")
    rf = MetaTaskKine6d("contactRF", robot, "RF", "right-ankle")
    com = MetaTaskKineCom(robot)
    sot = add_sot(robot, solver=solver)
    sot.addContact(lf)
    attime(0.01, lambda: sot.rmContact(lf), "remove the last contact")
    attime(0.02, lambda: (sot.addContact(rf), sot.push(com.task.name)), "then go on")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    with caplog.at_level(logging.WARNING, logger="sotdrake.entity"):
        simulator.AdvanceTo(0.05)
    context = simulator.get_context()
    assert context.get_time() == pytest.approx(0.05)
    assert sot.contacts(context) == ["taskcontactLF", "taskcontactRF"] and sot.stack(context) == ["taskcom"]
    assert [t for t, _ in sot.refused_commands] == [0.01] and "last contact" in sot.refused_commands[0][1]
    assert any("refused" in r.message for r in caplog.records)
    simulator.AdvanceTo(0.06)  # and the simulator still advances
    Simulator(diagram).AdvanceTo(0.05)  # a second run meets the same refusal: the record keeps it once
    assert [t for t, _ in sot.refused_commands] == [0.01]


# --- the shared fall criterion ------------------------------------------------------------------
def test_fall_report_names_the_first_reason():
    t = np.linspace(0.0, 1.0, 11)
    upright = np.zeros(11)
    standing = fall_report(t, upright, np.ones(11), np.zeros(11), np.zeros(11))
    assert not standing["fell"] and standing["fell_at_s"] is None and standing["fall_reason"] is None
    tilt = np.r_[np.zeros(5), np.full(6, FALL_TILT_DEG + 1)]
    assert fall_report(t, tilt, np.ones(11)) | {} == {
        "fell": True, "fell_at_s": 0.5, "fall_reason": "tilt", "max_base_tilt_deg": FALL_TILT_DEG + 1, "max_base_drop_m": 0.0}
    drop = fall_report(t, upright, np.r_[np.ones(7), np.full(4, 1 - FALL_BASE_DROP_M - 0.01)])
    assert drop["fall_reason"] == "base drop" and drop["fell_at_s"] == pytest.approx(0.7)
    slip = fall_report(t, upright, np.ones(11), np.r_[np.zeros(8), np.full(3, FALL_SLIP_M + 1e-3)], np.zeros(11))
    assert slip["fall_reason"] == "slip" and slip["fell_at_s"] == pytest.approx(0.8)
    contact = fall_report(t, upright, np.ones(11), other_contact=np.r_[np.zeros(9), [50.0, 50.0]])
    assert contact["fall_reason"] == "contact" and contact["max_other_contact_n"] == 50.0
    lost = fall_report(t, np.r_[np.zeros(3), np.full(8, np.nan)], np.ones(11))
    assert lost["fall_reason"] == "non-finite" and lost["fell_at_s"] == pytest.approx(0.3)
    # Just under every threshold: standing.
    near = fall_report(t, np.full(11, FALL_TILT_DEG - 0.1), np.full(11, 1.0) - np.r_[0, np.full(10, FALL_BASE_DROP_M - 0.01)],
                       np.full(11, FALL_SLIP_M - 1e-3))
    assert not near["fell"]
    with pytest.raises(ValueError):
        fall_report(t, upright[:5], np.ones(11))


def test_the_tilt_from_a_quaternion_and_from_a_rotation_agree():
    from pydrake.math import RollPitchYaw, RotationMatrix

    rng = np.random.default_rng(3)
    for _ in range(20):
        R = RotationMatrix(RollPitchYaw(rng.uniform(-1.5, 1.5, 3)))
        quaternion = R.ToQuaternion().wxyz()
        expected = np.degrees(np.arccos(R.matrix()[2, 2]))
        assert tilt_of_quaternions(quaternion[None])[0] == pytest.approx(expected, abs=1e-6)
        assert tilt_of_rotations(R.matrix()[None])[0] == pytest.approx(expected, abs=1e-9)


# --- one robot per builder, a task from another robot -------------------------------------------
def test_a_second_robot_in_a_builder_is_refused_and_the_first_still_builds(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    with pytest.raises(InvalidInput, match="one robot per DiagramBuilder"):
        Robot(builder, talos_model)
    add_sot(robot)
    diagram = builder.Build()
    Simulator(diagram).AdvanceTo(0.002)
    with pytest.raises(SotError, match="already built"):
        Robot(builder, talos_model)


# --- the review's bad inputs ---------------------------------------------------------------------
REVIEWED = ("talos twice", "sot.push(another", "sot.addContact(another", "gotoNd(rh, RigidTransform", "Robot(q0",
            "hold_move_hold", "simulate(", "talos(dt=", "posture.selectDof", "load_robot(")


def test_the_reviewed_bad_inputs_raise_a_sot_error_and_change_nothing():
    table = bad_inputs()
    chosen = [i for i, (label, _) in enumerate(table) if label.startswith(REVIEWED)]
    assert len(chosen) >= 20
    results = run_attempts("bad", "cascade", chosen)
    failures = {table[i][0]: r for i, r in results.items() if r.get("status") != "sot_error" or not r.get("unchanged")}
    assert not failures and len(results) == len(chosen)
