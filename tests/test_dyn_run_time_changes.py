"""The dynamic SoT's commands at run time and its builders' refusals: timed gain changes compose, a
contact released anew starts a new ramp, a feature's mask may change under a dynamic task (its
drift and reference acceleration follow), and a refused robot, plant or trajectory leaves the
builder as it was."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake import attime
from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynMomentum, MetaTaskDynPosture
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.dynamics.task_dyn_pd import TaskDynPD
from sotdrake.dynamics.trajectories import minimum_jerk_moves, trajectory_ports
from sotdrake.exceptions import InvalidInput, SotError, StackError
from sotdrake.physics import Push, add_physical_talos
from sotdrake.robots import load_robot, load_talos
from tests.conftest import random_configuration


def _robot(extra=None):
    """TALOS on the dynsimu device, both soles held, the CoM and the posture pushed; ``extra(robot,
    tasks)`` runs before the build (timed commands, more tasks)."""
    builder = DiagramBuilder()
    robot = RobotDyn(builder, load_talos("reduced"), "dynsimu")
    contacts = [robot.add_contact("contactLF", "left-sole"), robot.add_contact("contactRF", "right-sole")]
    tasks = {"com": MetaTaskDynCom(robot), "posture": MetaTaskDynPosture(robot), "rh": MetaTaskDyn6d("rh", robot, "rh", "right-wrist"),
             "momentum": MetaTaskDynMomentum(robot)}
    if extra is not None:
        extra(robot, tasks)
    for contact in contacts:
        robot.sot.addContact(contact)
    robot.sot.push(tasks["com"].task.name)
    robot.sot.push(tasks["posture"].task.name)
    return robot, builder.Build(), tasks


@pytest.fixture(scope="module")
def dyn():
    return _robot()


def test_timed_gain_changes_of_one_task_compose():
    """``setKv`` then ``setKp`` at later times: each keeps the other gain as the run has it then
    (the second used to put back the default it read when it was recorded)."""

    def timed(robot, tasks):
        com, contact = tasks["com"].task, robot.contacts["contactLF"]
        attime(0.01, lambda: com.setKv(30.0))
        attime(0.02, lambda: com.setKp(400.0))
        attime(0.01, lambda: contact.setPositionGain(100.0))
        attime(0.02, lambda: contact.setVelocityGain(20.0))

    robot, diagram, tasks = _robot(timed)
    simulator = Simulator(diagram)
    simulator.AdvanceTo(0.025)
    context = simulator.get_context()
    settings, contact = tasks["com"].task.settings(context), robot.contacts["contactLF"].settings(context)
    assert (settings.kp, settings.kv) == (400.0, 30.0)
    assert (contact.position_gain, contact.velocity_gain) == (100.0, 20.0)
    assert tasks["com"].task.refused_commands == [] and robot.contacts["contactLF"].refused_commands == []


def test_a_timed_gain_that_makes_the_loop_unstable_with_the_other_is_refused_at_its_time():
    def timed(robot, tasks):
        attime(0.01, lambda: tasks["com"].task.setKv(1500.0))  # with K_p = 100 at 1 ms: stable
        attime(0.02, lambda: tasks["com"].task.setKp(2e6))  # with K_v = 1500: 2 + 3 ≥ 4, unstable

    robot, diagram, tasks = _robot(timed)
    simulator = Simulator(diagram)
    simulator.AdvanceTo(0.025)
    settings = tasks["com"].task.settings(simulator.get_context())
    assert (settings.kp, settings.kv) == (100.0, 1500.0)
    ((time, message),) = tasks["com"].task.refused_commands
    assert time == pytest.approx(0.02) and "unstable" in message


def test_a_contact_held_again_and_released_anew_in_one_tick_starts_a_new_ramp(dyn):
    """The second release ramps from the force carried when it starts, over its own duration (it
    used to go on with the first one's ramp and end with it)."""
    robot, diagram, _ = dyn
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    simulator.AdvanceTo(0.0105)
    robot.sot.rmContact("contactRF", 0.02, context)  # would end near 0.031 s
    simulator.AdvanceTo(0.0205)
    robot.sot.addContact("contactRF", context)
    robot.sot.rmContact("contactRF", 0.02, context)  # a new ramp from 0.021 s: ends near 0.041 s
    simulator.AdvanceTo(0.0355)
    assert robot.sot.contacts(context) == ["contactLF", "contactRF"]
    simulator.AdvanceTo(0.0455)
    assert robot.sot.contacts(context) == ["contactLF"]


def test_another_robots_contact_is_refused(dyn):
    robot, diagram, _ = dyn
    other = RobotDyn(DiagramBuilder(), load_talos("reduced"), "dynsimu").add_contact("contactRF", "left-sole")
    context = diagram.CreateDefaultContext()
    with pytest.raises(StackError, match="'contactRF' given is not the one this solver reads"):
        robot.sot.rmContact(other, 0.1, context)
    assert robot.sot.contacts(context) == ["contactLF", "contactRF"]
    robot.sot.rmContact(robot.contacts["contactRF"], 0.1, context)  # its own: accepted


@pytest.mark.parametrize(("task", "mask"), [("com", "011"), ("rh", "000111"), ("momentum", "111111"), ("momentum", "100")])
def test_a_dynamic_tasks_rows_follow_its_features_mask(dyn, task, mask):
    """After ``feature.selec(mask)`` at run time the task's rows are the full task's selected rows
    (the exact drift and the reference acceleration take the same components as the error)."""
    robot, diagram, tasks = dyn
    meta = tasks[task]
    context = diagram.CreateDefaultContext()
    rng = np.random.default_rng(7)
    q = random_configuration(robot.model, rng, spread=0.3)
    robot.device.GetMyContextFromRoot(context).SetDiscreteState(np.concatenate([q, rng.normal(0.0, 0.5, robot.model.nv)]))
    full_mask = "1" * meta.feature.dimension
    meta.feature.selec(full_mask, context)
    own = meta.task.GetMyContextFromRoot(context)
    full = meta.task.GetOutputPort("task").Eval(own)
    meta.feature.selec(mask, context)
    selected = meta.task.GetOutputPort("task").Eval(own)
    rows = [i for i, flag in enumerate(reversed(mask)) if flag == "1"]
    np.testing.assert_array_equal(selected.jacobian, full.jacobian[rows])
    np.testing.assert_allclose(selected.lower, full.lower[rows], rtol=1e-12, atol=1e-12)


def test_a_dynamic_com_task_needs_a_floating_base():
    robot = RobotDyn(DiagramBuilder(), load_robot("ur5"), "dynsimu")
    with pytest.raises(InvalidInput, match=r"MetaTaskDynCom.*no floating base"):
        MetaTaskDynCom(robot)
    assert robot.builder.GetSystems()[-1].get_name() == "device"  # nothing added


def test_a_task_without_a_feature_is_refused_when_pushed(dyn):
    robot, diagram, _ = dyn
    builder = DiagramBuilder()
    bare = RobotDyn(builder, load_talos("reduced"), "dynsimu")
    bare.add_task(TaskDynPD("taskbare", bare.dimension, bare.dt))
    diagram = builder.Build()
    with pytest.raises(StackError, match=r"'taskbare' has no feature.*MetaTaskDyn6d"):
        bare.sot.push("taskbare", diagram.CreateDefaultContext())


def test_a_physics_step_too_long_is_refused_by_name_before_anything_is_added():
    builder = DiagramBuilder()
    with pytest.raises(InvalidInput, match=r"dt \(the control period, the physics plant's step\)"):
        RobotDyn(builder, load_talos("reduced"), "physics", dt=0.05)
    assert builder.GetSystems() == []
    RobotDyn(builder, load_talos("reduced"), "physics", dt=0.002)  # the same builder takes a good one


@pytest.mark.parametrize("options", [{"stiffness": -1.0}, {"damping": float("nan")}, {"variant": "no such variant"}])
def test_a_refused_physical_talos_leaves_the_builder_as_it_was(options):
    builder = DiagramBuilder()
    with pytest.raises(SotError):
        add_physical_talos(builder, **options)
    assert builder.GetSystems() == []


@pytest.mark.parametrize("samples", [0, 1, -3, 2.5, "24", None])
def test_minimum_jerk_moves_refuse_a_sample_count_that_is_not_two_or_more(samples):
    with pytest.raises(InvalidInput, match="samples"):
        minimum_jerk_moves(np.zeros(1), [(1.0, 2.0, np.ones(1))], samples=samples)


def test_trajectory_ports_refuse_a_taken_name_or_a_non_trajectory_before_adding_anything(dyn):
    builder = DiagramBuilder()
    robot = RobotDyn(builder, load_talos("reduced"), "dynsimu")
    trajectory = minimum_jerk_moves(np.zeros(1), [(0.1, 0.2, np.ones(1))])
    robot.add(TaskDynPD("ref_split", robot.dimension, robot.dt))  # any system by that name
    count = len(builder.GetSystems())
    with pytest.raises(InvalidInput, match="'ref_split' already exists"):
        trajectory_ports(robot, trajectory, "ref")
    with pytest.raises(InvalidInput, match="must be a PiecewisePolynomial"):
        trajectory_ports(robot, "not a trajectory", "ref2")
    assert len(builder.GetSystems()) == count
    trajectory_ports(robot, trajectory, "ref3")


def test_push_times_may_be_numpy_scalars():
    force = Push.check_arguments([100.0, 0.0, 0.0], np.int64(1), np.float32(0.1))
    np.testing.assert_array_equal(force, [100.0, 0.0, 0.0])
    with pytest.raises(InvalidInput, match="duration > 0"):
        Push.check_arguments([100.0, 0.0, 0.0], np.float64(1.0), np.float32(0.0))


def test_velocity_selection_of_a_dynamic_robot_refuses_one_string(dyn):
    robot, _, _ = dyn
    with pytest.raises(InvalidInput, match="excluding is a list of joint names"):
        robot.velocity_selection(excluding="arm_left_1_joint")
    assert not robot.velocity_selection(excluding=["arm_left_1_joint"]).all()
