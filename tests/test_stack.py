"""Stack commands, context semantics (defaults, per-context, clone) and the attime sequencer."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake.exceptions import InvalidInput, SolverError, SotError, SotWarning, StackError, TaskNotFound
from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, gotoNd
from sotdrake.robot import Robot, add_sot
from sotdrake.robots import TALOS_GRIPPERS
from sotdrake.sequencer import attime
from sotdrake.solvers import SOT
from sotdrake.task import Task, TaskLevel


def build(model, with_sequence=True):
    builder = DiagramBuilder()
    robot = Robot(builder, model)
    rh = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    lf = MetaTaskKine6d("lf", robot, "lf", "left-ankle")
    com = MetaTaskKineCom(robot)
    sot = add_sot(robot)  # created after the tasks: still connected to all of them
    lh = MetaTaskKine6d("lh", robot, "lh", "left-wrist")  # and to the ones created after
    sot.setControlSelection(robot.velocity_selection(TALOS_GRIPPERS))
    sot.push(lf.task.name)
    sot.push(com.task.name)
    gotoNd(rh, (0.4, -0.3, 1.0), "111", 2.0)
    if with_sequence:
        attime(0.05, lambda: sot.push(rh.task.name), "push rh")
        attime(0.10, (lambda: (sot.remove(com.task.name), gotoNd(rh, (0.45, -0.3, 1.0))), "drop com"))
    return robot, sot, (rh, lf, com, lh), builder.Build()


def test_stack_commands_and_errors_leave_the_stack_unchanged(talos_model):
    robot, sot, (rh, lf, com, lh), diagram = build(talos_model, with_sequence=False)
    context = diagram.CreateDefaultContext()
    assert sot.stack(context) == ["tasklf", "taskcom"]
    assert set(sot.known_tasks) == {"taskrh", "tasklf", "taskcom", "tasklh"}
    sot.push("tasklh", context)
    sot.remove("taskcom", context)
    assert sot.stack(context) == ["tasklf", "tasklh"]
    for bad, error in [(lambda: sot.push("tasklf", context), StackError),
                       (lambda: sot.push("taskunknown", context), TaskNotFound),
                       (lambda: sot.remove("taskcom", context), StackError)]:
        with pytest.raises(error):
            bad()
        assert sot.stack(context) == ["tasklf", "tasklh"]
    sot.pop(context)
    sot.clear(context)
    with pytest.raises(StackError):
        sot.pop(context)
    assert sot.stack(context) == []
    assert sot.stack(diagram.CreateDefaultContext()) == ["tasklf", "taskcom"]  # defaults untouched
    assert sot.stack() == ["tasklf", "taskcom"]


def test_empty_stack_gives_zero_velocity(talos_model):
    robot, sot, _, diagram = build(talos_model, with_sequence=False)
    context = diagram.CreateDefaultContext()
    sot.clear(context)
    control = sot.GetOutputPort("control").Eval(sot.GetMyContextFromRoot(context))
    assert np.all(control == 0)


def test_attime_sequence_replays_bit_for_bit_in_a_cloned_context(talos_model):
    robot, sot, (rh, lf, com, lh), diagram = build(talos_model)
    simulator = Simulator(diagram)
    start = simulator.get_context().Clone()
    simulator.AdvanceTo(0.049)
    assert sot.stack(simulator.get_context()) == ["tasklf", "taskcom"]
    simulator.AdvanceTo(0.07)
    assert sot.stack(simulator.get_context()) == ["tasklf", "taskcom", "taskrh"]
    simulator.AdvanceTo(0.2)
    context = simulator.get_context()
    assert sot.stack(context) == ["tasklf", "taskrh"]
    np.testing.assert_allclose(rh.featureDes.settings(context).position.translation(), [0.45, -0.3, 1.0])
    q_first = robot.device.position(context)
    assert np.linalg.norm(q_first - robot.device.initial_position) > 1e-3  # it moved

    replay = Simulator(diagram, start)
    replay.AdvanceTo(0.2)
    assert np.array_equal(robot.device.position(replay.get_context()), q_first)
    assert sot.stack() == ["tasklf", "taskcom"]  # the defaults are not the sequence's


def test_attime_rejects_what_it_cannot_schedule(talos_model):
    robot, sot, (rh, *_), _ = build(talos_model, with_sequence=False)
    with pytest.raises(SotError):
        attime(1.0, lambda: None, "does nothing")
    with pytest.raises(SotError):
        attime(-1.0, lambda: sot.push(rh.task.name))
    with pytest.raises(SotError):
        attime(1.0, lambda: rh.keep())  # needs the state at T: use a context instead
    with pytest.raises(TaskNotFound):
        attime(1.0, lambda: sot.push("tasknothing"))


def test_attime_after_a_context_exists_warns_and_runs_only_if_its_time_is_ahead(talos_model):
    robot, sot, (rh, lf, com, lh), diagram = build(talos_model, with_sequence=False)
    simulator = Simulator(diagram)
    simulator.AdvanceTo(0.02)
    with pytest.warns(SotWarning, match="past T never runs"):
        attime(0.01, lambda: sot.push(rh.task.name), "late")
    with pytest.warns(SotWarning, match="past T never runs"):
        attime(0.03, lambda: sot.push(lh.task.name), "ahead")
    simulator.AdvanceTo(0.05)
    assert sot.stack(simulator.get_context()) == ["tasklf", "taskcom", "tasklh"]


def test_non_finite_task_is_reported_with_its_name(talos_model):
    sot = SOT("sot", talos_model.nv)
    task = Task("taskbad", talos_model.nv)
    port = sot.declare_task_input(task)
    sot.push("taskbad")
    context = sot.CreateDefaultContext()
    J = np.ones((2, talos_model.nv))
    port.FixValue(context, TaskLevel(J, np.array([1.0, np.nan]), np.array([1.0, np.nan]), np.zeros(2)))
    with pytest.raises(SolverError, match="taskbad"):
        sot.GetOutputPort("control").Eval(context)
    port.FixValue(context, TaskLevel(J[:, :3], np.ones(2), np.ones(2), np.zeros(2)))
    with pytest.raises(SolverError, match="taskbad"):
        sot.GetOutputPort("control").Eval(context)


def test_non_finite_configuration_is_an_error_not_an_abort(talos_model):
    robot, sot, _, diagram = build(talos_model, with_sequence=False)
    context = diagram.CreateDefaultContext()
    q = robot.device.initial_position.copy()
    q[10] = np.nan
    with pytest.raises(InvalidInput):
        robot.device.set_position(context, q)
    robot.device.GetMyContextFromRoot(context).SetDiscreteState(0, q)  # bypassing the checks
    with pytest.raises(InvalidInput, match="non-finite position"):
        sot.GetOutputPort("control").Eval(sot.GetMyContextFromRoot(context))


def test_add_contact_at_the_bottom_is_keep_then_push(talos_model):
    """``priority="bottom"``: sot-dyninv's kinematic addContact (``keep()`` then ``push``), below the
    tasks pushed before it; the default keeps the contact level above the whole stack."""
    robot, sot, (rh, lf, com, lh), diagram = build(talos_model, with_sequence=False)
    context = diagram.CreateDefaultContext()
    sot.clear(context)
    sot.push(rh, context)
    q = robot.device.position(context)
    q[robot.model.plant.GetJointByName("leg_left_1_joint").position_start()] += 0.1  # the left foot turns
    robot.device.set_position(context, q)
    sot.addContact(lf, context, priority="bottom")
    assert sot.stack(context) == ["taskrh", "tasklf"] and sot.contacts(context) == []
    target = lf.featureDes.settings(context).position
    now = lf.current_pose(context)
    assert np.allclose(target.GetAsMatrix4(), now.GetAsMatrix4(), atol=1e-12)  # kept where the foot is now
    assert not np.allclose(target.rotation().matrix(), lf.current_pose().rotation().matrix(), atol=1e-3)
    for bad, error in [(lambda: sot.addContact(lf, context, priority="bottom"), StackError),
                       (lambda: sot.addContact(lh, context, priority="middle"), InvalidInput),
                       (lambda: sot.addContact("taskunknown", context, priority="bottom"), TaskNotFound)]:
        with pytest.raises(error):
            bad()
        assert sot.stack(context) == ["taskrh", "tasklf"] and sot.contacts(context) == []
    sot.addContact(lh, context)  # the default: the contact level, above the stack
    assert sot.contacts(context) == ["tasklh"] and sot.stack(context) == ["taskrh", "tasklf"]
