"""SolverKine (hierarchical QP) in diagrams: the tutorial, joint limits, inequality tasks, failure."""


import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake.exceptions import InvalidInput, SolverError, StackError
from sotdrake.hqp.stack_paths import WarmQrSweep
from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, MetaTaskKinePosture, gotoNd
from sotdrake.robot import Robot, add_sot
from sotdrake.robots import TALOS_GRIPPERS
from sotdrake.scenarios import sot_concept as sot_concept_scenario
from sotdrake.scenarios import talos_appli
from sotdrake.solvers import HierarchicalQP, SolverKine


@pytest.fixture(scope="module")
def concept():
    return sot_concept_scenario


def test_tutorial_with_the_hqp_has_the_same_outcome():
    """The tutorial's reach under ``SolverKine``, judged as the tutorial's test judges it 2.5 s after
    the hand task is pushed. The push is at 0.2 s rather than 1 s: the idle ticks before it, where
    nothing may move, are 200 rather than 1000."""
    handles = talos_appli.build_diagram(solver="hqp", push_time=0.2)
    assert isinstance(handles.sot, SolverKine)
    simulator, wall = talos_appli.simulate(handles, 2.7, progress=False)
    summary, trace = talos_appli.summarize(handles, simulator, 2.7, wall)
    before = trace["time"] < 0.2
    assert before.sum() == 200 and np.ptp(trace["q"][before], axis=0).max() < 1e-12
    assert summary["final_stack"] == ["taskcontactRF", "taskcontactLF", "taskcom", "taskrh"]
    assert summary["hand_initial_error_m"] == pytest.approx(0.414, abs=1e-3)
    assert summary["hand_error_m"] < 5e-3
    assert summary["max_foot_drift_m"] < 1e-4 and summary["max_com_drift_m"] < 1e-4
    assert summary["min_joint_limit_margin_rad"] >= 0.0


def test_joint_limits_hold_with_the_hqp_and_not_with_the_cascade(concept):
    results = {}
    for name in ("extra_joint_limits", "extra_joint_limits_cascade"):
        config = dataclasses.replace(concept.CONFIGURATIONS[name], duration=1.5)
        handles = concept.build_diagram(config)
        simulator, wall = concept.run(handles, progress=False)
        results[name], _ = concept.summarize(handles, simulator, wall)
    assert results["extra_joint_limits"]["min_joint_limit_margin_rad"] >= 1e-3 - 1e-9  # the margin, kept
    assert results["extra_joint_limits_cascade"]["min_joint_limit_margin_rad"] < -1e-2  # crossed
    assert results["extra_joint_limits"]["max_joint_velocity_ratio"] <= 1.0 + 1e-9


def build_reach(model, com_kind, ball=(1.05, -0.35, 0.75), dt=1e-3, posture=False):
    builder = DiagramBuilder()
    robot = Robot(builder, model, dt)
    sot = add_sot(robot, solver="hqp")
    sot.setControlSelection(robot.velocity_selection(TALOS_GRIPPERS))
    for name, op in (("contactRF", "right-ankle"), ("contactLF", "left-ankle")):
        contact = MetaTaskKine6d(name, robot, name[-2:], op)
        contact.gain.setConstant(10)
        sot.push(contact.task.name)
    com = MetaTaskKineCom(robot, inequality=com_kind == "box")
    com.gain.setConstant(10)
    if com_kind == "box":
        com.feature.selec("011")
        com.task.setBounds([-0.03, -0.03], [0.03, 0.03])  # CoM within ±3 cm of where it starts
    sot.push(com.task.name)
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    gotoNd(hand, ball, "111", 5.0)
    sot.push(hand.task.name)
    if posture:  # the half-sitting posture at the bottom
        task = MetaTaskKinePosture(robot)
        task.gain.setConstant(1.0)
        sot.push(task.task.name)
    return robot, sot, hand, com, builder.Build()


def test_inequality_tasks_mix_with_equality_tasks(talos_model):
    # 300 ticks of 2 ms per case: by then the box's CoM sits on its bound and the hand is 6 cm closer.
    outcome = {}
    for kind in ("held", "box"):
        robot, sot, hand, com, diagram = build_reach(talos_model, kind, dt=2e-3)
        simulator = Simulator(diagram)
        simulator.AdvanceTo(0.6 - 1e-3)
        context = simulator.get_context()
        q = robot.device.position(context)
        shift = robot.dynamic.com_at(q)[:2] - robot.dynamic.com_at(robot.device.initial_position)[:2]
        outcome[kind] = (np.linalg.norm(hand.current_pose(context).translation() - [1.05, -0.35, 0.75]), shift)
        diagnostics = sot.GetOutputPort("diagnostics").Eval(sot.GetMyContextFromRoot(context))
        assert diagnostics.failure == "" and len(diagnostics.slack_norms) == 4
    held, box = outcome["held"], outcome["box"]
    assert np.all(np.abs(box[1]) <= 0.03 + 1e-4)  # the CoM stays in its box …
    assert np.abs(box[1]).max() > 0.02  # … and uses it
    assert box[0] < held[0] - 0.01  # so the hand gets closer than with the CoM held exactly
    assert np.abs(held[1]).max() < 1e-4


def test_the_basic_sot_refuses_inequality_tasks(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    sot = add_sot(robot)
    com = MetaTaskKineCom(robot, inequality=True)
    with pytest.raises(StackError, match="hqp"):
        sot.push(com.task.name)
    assert sot.stack() == []


def test_a_failing_level_holds_the_device_and_says_why(talos_model, monkeypatch, caplog):
    robot, sot, hand, com, diagram = build_reach(talos_model, "held")

    def fail(self, *args, **kwargs):
        raise SolverError("hierarchical QP: no solution on level 3 (clarabel: kIterationLimit)")

    monkeypatch.setattr(HierarchicalQP, "solve", fail)
    monkeypatch.setattr(HierarchicalQP, "solve_equalities", lambda self, *args, **kwargs: None)  # (its equality-stack paths)
    monkeypatch.setattr(WarmQrSweep, "attempt", lambda self, *args, **kwargs: None)
    context = diagram.CreateDefaultContext()
    own = sot.GetMyContextFromRoot(context)
    with caplog.at_level("WARNING", logger="sotdrake.solver_kine"):
        control = sot.GetOutputPort("control").Eval(own)
    assert np.all(control == 0) and np.all(np.isfinite(control))
    assert "level 3" in sot.GetOutputPort("diagnostics").Eval(own).failure
    assert any("device holds" in r.getMessage() for r in caplog.records)


def test_solver_kine_inputs(talos_model):
    with pytest.raises(InvalidInput):
        SolverKine("s", talos_model, 1e-3, solver="quadprog")
    kine = SolverKine("s", talos_model, 1e-3)
    for bad in (lambda: kine.setPositionMargin(-1.0), lambda: kine.setSolver("cvx"), lambda: kine.setDamping(np.nan)):
        with pytest.raises(InvalidInput):
            bad()
    with pytest.raises(InvalidInput):
        add_sot(Robot(DiagramBuilder(), talos_model), solver="soth")


def test_a_velocity_limit_is_a_hard_bound_and_the_svd_threshold_is_refused(talos_model):
    """Both were accepted and ignored: the command went on to the model's limits (20 times the
    limit set), and a threshold changed nothing."""
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    sot = add_sot(robot, solver="hqp")
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    gotoNd(hand, (0.6, -0.5, 1.2), "111", 50.0)
    sot.push(hand.task.name)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    control = sot.GetOutputPort("control")
    assert np.abs(control.Eval(sot.GetMyContextFromRoot(context))).max() > 0.5
    limit = np.full(talos_model.nv, 0.1)
    limit[20] = 0.01
    sot.setVelocityLimit(limit, context)
    v = control.Eval(sot.GetMyContextFromRoot(context))
    assert np.all(np.abs(v) <= limit * (1 + 1e-9)) and np.abs(v).max() > 0.09
    with pytest.raises(StackError, match="setThreshold"):
        sot.setThreshold(1e-3, context)


def test_concept_script_writes_one_entry_per_configuration(concept, tmp_path):
    summary = concept.main(["--config", "all", "--duration", "0.1", "--out", str(tmp_path), "--no-meshcat", "--quiet"])
    assert set(summary) == set(concept.CONFIGURATIONS)
    for entry in summary.values():
        for key in ("hand_error_m", "com_error_m", "level_slacks", "min_joint_limit_margin_rad", "max_joint_velocity_ratio"):
            assert key in entry
    assert (tmp_path / "plots.png").is_file() and (tmp_path / "summary.json").is_file()
    assert (tmp_path / "extra_joint_limits" / "trace.npz").is_file() and (tmp_path / "seed5" / "trace.npz").is_file()


def test_randomized_robot_runs_never_freeze_and_keep_the_limits(talos_model):
    """A fast subset of bench/hqp_robot_runs.py (which runs 300): random stacks of feet, CoM (held
    or in a box), hands near and far, posture, from random starts with joints on their limits."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
    import hqp_robot_runs

    runs = hqp_robot_runs.build(talos_model)
    active = 0
    for seed in range(24):
        result = hqp_robot_runs.one_run(runs, np.random.default_rng(10_000 + seed), ticks=25)
        assert result["frozen_ticks"] == 0, (seed, result["failures"])
        assert result["position_limit_violations"] == 0 and result["velocity_limit_violations"] == 0, seed
        active += result["ticks_with_active_limits"]
    assert active > 0  # the limits were in play


def test_a_posture_at_the_bottom_gives_the_stages_motion(talos_model, monkeypatch):
    """The usual stack (feet, CoM, a hand driven out of reach, the posture at the bottom: more rows
    than what is left free) moves TALOS as the level-by-level stages alone would, tick by tick,
    joint limits reached included: the whole-stack paths that answer it give the stages' answer."""
    from sotdrake.hqp import stack_paths
    from sotdrake.solvers import solver_kine

    def run(paths):
        monkeypatch.setattr(solver_kine, "KINEMATIC", paths)
        robot, sot, _, _, diagram = build_reach(talos_model, "held", dt=2e-3, posture=True)
        simulator = Simulator(diagram)
        positions, limits = [], 0
        for k in range(1, 201):
            simulator.AdvanceTo(k * 2e-3 - 1e-3)
            context = simulator.get_context()
            diagnostics = sot.GetOutputPort("diagnostics").Eval(sot.GetMyContextFromRoot(context))
            assert diagnostics.failure == ""
            limits = max(limits, len(diagnostics.active_limits))
            positions.append(robot.device.position(context))
        return np.array(positions), limits

    default, limits = run(stack_paths.KINEMATIC)
    stages, _ = run((stack_paths.STAGES,))
    assert limits >= 1  # the hand out of reach brings joints to their limits
    np.testing.assert_allclose(default, stages, rtol=0, atol=1e-9)
