"""The kinematic robot's builders and commands under mistakes: a refusal leaves the builder as it
was (a robot's bad `dt`, a solver's taken limitator name, a weighted level named like one of the
solver's inputs), an op point is not declared once the diagram is built, a timed weight changes its
member only, a command keeps no reference to the caller's arrays, and the fall criterion and the
runner refuse what they cannot use."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake import (
    JointLimitator,
    MetaTaskKine6d,
    MetaTaskKinePosture,
    Solver,
    add_sot,
    add_task_weight,
    attime,
    fall_report,
    load_robot,
    robot,
    tilt_of_quaternions,
    tilt_of_rotations,
)
from sotdrake.exceptions import FrameNotFound, InvalidInput, SotError
from sotdrake.interactive import Runner


def _names(builder: DiagramBuilder) -> list[str]:
    return sorted(system.get_name() for system in builder.GetSystems())


def test_an_op_point_is_not_declared_once_the_diagram_is_built():
    """Its port would be missing from the contexts made before (reading it ended the process)."""
    builder = DiagramBuilder()
    arm = robot(builder, "ur5")
    pose, _ = arm.dynamic.createOpPoint("tool_point", "tool")
    builder.Build()
    with pytest.raises(SotError, match="cannot create the op point 'late': the diagram is already built"):
        arm.dynamic.createOpPoint("late", "tool")
    assert arm.dynamic.createOpPoint("tool_point", "tool")[0] is pose  # an existing one is still given


def test_a_robot_refused_for_its_period_leaves_the_builder_empty():
    builder = DiagramBuilder()
    with pytest.raises(InvalidInput, match="dt"):
        robot(builder, "ur5", dt=0.0)
    assert _names(builder) == []
    robot(builder, "ur5")


@pytest.mark.parametrize("options", [{"limitator_name": "device"}, {"name": "x", "limitator_name": "x"}])
def test_a_solver_refused_for_its_names_leaves_the_robot_without_one(options):
    builder = DiagramBuilder()
    arm = robot(builder, "ur5")
    with pytest.raises(InvalidInput):
        Solver(arm, **options)
    assert _names(builder) == ["device", "dynamic"] and arm.solver is None
    Solver(arm)


def test_a_weighted_level_named_like_a_solver_input_is_refused_before_anything_is_added():
    builder = DiagramBuilder()
    arm = robot(builder, "ur5")
    hand, posture = MetaTaskKine6d("rh", arm, "tool"), MetaTaskKinePosture(arm)
    add_sot(arm, solver="hqp")  # its inputs: the tasks' and "position"
    before = (_names(builder), sorted(arm.tasks))
    with pytest.raises(InvalidInput, match="'position': the solver sot has an input of that name"):
        add_task_weight(arm, "position", [hand, posture])
    assert (_names(builder), sorted(arm.tasks)) == before
    add_task_weight(arm, "group", [hand, posture])
    builder.Build()


def test_a_timed_weight_changes_its_member_only():
    """The member not named keeps the weight the run gave it (it used to get back the default it
    had when the timed command was recorded)."""
    builder = DiagramBuilder()
    arm = robot(builder, "ur5")
    hand, posture = MetaTaskKine6d("rh", arm, "tool"), MetaTaskKinePosture(arm)
    group = add_task_weight(arm, "group", [hand, posture], [1.0, 0.01])
    add_sot(arm).push(group)
    attime(0.05, lambda: group.setWeight(posture, 0.5))
    simulator = Simulator(builder.Build())
    context = simulator.get_mutable_context()
    simulator.AdvanceTo(0.02)
    group.setWeight(hand, 2.0, context)
    simulator.AdvanceTo(0.1)
    assert group.weights(context) == {"taskrh": 2.0, "taskposture": 0.5}


@pytest.mark.parametrize("weight", [10**400, "x", float("nan"), -1.0, np.array([1.0, 2.0])])
def test_a_weight_that_is_not_a_finite_number_is_refused_by_its_value(weight):
    builder = DiagramBuilder()
    arm = robot(builder, "ur5")
    group = add_task_weight(arm, "group", [MetaTaskKine6d("rh", arm, "tool"), MetaTaskKinePosture(arm)])
    with pytest.raises(InvalidInput, match="the weight of 'taskrh' must be a finite number"):
        group.setWeight("taskrh", weight)
    group.setWeight("taskrh", np.array(3.0))  # a numpy 0-d array or scalar is a number
    group.setWeights({"taskposture": np.float32(0.5)})
    assert group.weights() == {"taskrh": 3.0, "taskposture": 0.5}


def test_a_command_keeps_no_reference_to_the_callers_arrays():
    limitator = JointLimitator(load_robot("ur5").plant, 1e-3)
    for where in (None, "context"):
        where = limitator.CreateDefaultContext() if where else None
        lower, upper = -np.ones(6), np.ones(6)
        limitator.setLimits(lower, upper, where)
        lower[:], upper[0] = np.nan, -5.0
        np.testing.assert_array_equal(limitator.limits(where)[0], -np.ones(6))
        np.testing.assert_array_equal(limitator.limits(where)[1], np.ones(6))


def test_a_frame_given_as_a_list_is_not_found():
    arm = robot(DiagramBuilder(), "ur5")
    with pytest.raises(FrameNotFound):
        arm.dynamic.pose_at(["tool"], arm.model.half_sitting)


def test_the_runner_never_steps_back_after_a_time_between_ticks():
    builder = DiagramBuilder()
    arm = robot(builder, "ur5")
    add_sot(arm)
    runner = Runner(builder.Build(), np.float64(1e-3))
    runner.advance_to(0.0104)
    assert runner.step(0) == pytest.approx(0.0104)
    assert runner.step(1) == pytest.approx(0.011)
    with pytest.raises(InvalidInput, match="built Diagram"):
        Runner(builder, 1e-3)


@pytest.mark.parametrize(("call", "named"), [
    (lambda: fall_report([0.0, 1.0], [0.0], [1.0, 1.0]), "one sample per time"),
    (lambda: fall_report([0.0, 1.0], [0.0, 0.0], [1.0, 1.0], sole_slip=[0.0]), "one sample per time"),
    (lambda: fall_report([], [], []), "T = 0"),
    (lambda: fall_report([0.0], [np.nan], [1.0]), "first sample must be finite"),
    (lambda: fall_report(["a"], [0.0], [1.0]), "time"),
    (lambda: tilt_of_quaternions([1.0, 0.0, 0.0, 0.0]), "T × 4"),
    (lambda: tilt_of_quaternions([[1.0, 0.0, 0.0]]), "T × 4"),
    (lambda: tilt_of_rotations(np.eye(3)), "T × 3 × 3"),
])
def test_the_fall_criterion_refuses_series_it_cannot_read(call, named):
    with pytest.raises(InvalidInput, match=named):
        call()


def test_a_non_finite_slip_is_a_fall_not_a_zero():
    report = fall_report([0.0, 0.1, 0.2], [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], sole_slip=[0.0, np.inf, 0.0])
    assert (report["fell"], report["fell_at_s"], report["fall_reason"]) == (True, 0.1, "non-finite")
