"""The dynamic SoT's remaining entry points check what they are given: a contact's ``dt`` and kept
rotation, the solver's contact names, unconnected inputs of hand-wired entities, a task's infinite
reference, the trajectories' times and names, the dynamic entity's op points and configurations,
``friction_ratio`` of a pulling force; and the tutorial's snippet does what its script does.

Each refusal is a :class:`~sotdrake.exceptions.SotError` naming the argument, raised before
anything changes."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import DiagramBuilder

import sotdrake
from sotdrake import friction_ratio, hold_move_hold, minimum_jerk_moves, trajectory_ports
from sotdrake.dynamics.contact import Contact6d
from sotdrake.dynamics.device import RobotDynSimu
from sotdrake.dynamics.dyn_types import ContactNotFound
from sotdrake.dynamics.dynamic_entity import DynamicEntity
from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDynCom
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.dynamics.solver_dyn import SolverDyn
from sotdrake.exceptions import InvalidInput, NotFound, SolverError, StackError

ROOT = Path(__file__).resolve().parents[1]
SOLE = (-0.1, 0.1, -0.05, 0.05)
NAN, INF = float("nan"), float("inf")


@pytest.fixture(scope="module")
def dyn(talos_model):
    """A dynsimu robot: both soles declared and held, the CoM task pushed (its diagram: ``built``)."""
    builder = DiagramBuilder()
    robot = RobotDyn(builder, talos_model, "dynsimu")
    for name, sole in (("contactLF", "left-sole"), ("contactRF", "right-sole")):
        robot.sot.addContact(robot.add_contact(name, sole))
    com = MetaTaskDynCom(robot)
    robot.sot.push(com.task.name)
    return robot, builder, com


@pytest.fixture(scope="module")
def built(dyn):
    robot, builder, com = dyn
    return robot, builder.Build(), com


# --- a contact's dt --------------------------------------------------------------------------
@pytest.mark.parametrize("dt", [-1e-3, -1.0, NAN, INF, 0.0, 2.0, "0.001", True, [1e-3]])
def test_a_contacts_dt_is_checked_as_the_solvers(talos_model, dt):
    with pytest.raises(InvalidInput, match=r"c: dt"):
        Contact6d("c", 6, SOLE, dt=dt)
    with pytest.raises(InvalidInput, match=r"s: dt"):  # (the same range as the solver's)
        SolverDyn("s", talos_model, dt)


def test_a_contact_with_a_valid_dt_checks_its_gains_against_it():
    contact = Contact6d("c", 6, SOLE, dt=1e-2)
    assert contact.dt == 1e-2 and contact.settings().velocity_gain == pytest.approx(15.0)
    contact.setVelocityGain(150.0)  # 2 K_v dt = 3 < 4
    with pytest.raises(InvalidInput, match="Kp dt² \\+ 2 Kv dt"):
        contact.setVelocityGain(200.0)  # 2 K_v dt = 4
    assert contact.settings().velocity_gain == 150.0
    assert Contact6d("c", 6, SOLE).dt is None  # (no dt: not checked against one)


# --- a contact's kept rotation ---------------------------------------------------------------
@pytest.mark.parametrize("matrix", [np.zeros((3, 3)), np.diag([1.0, 1.0, -1.0]), np.diag([2.0, 1.0, 1.0]),
                                    np.array([[1.0, 1e-3, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])])
def test_keep_refuses_a_matrix_that_is_not_a_rotation(matrix):
    contact = Contact6d("c", 6, SOLE, dt=1e-3)
    before = contact.settings().kept
    with pytest.raises(InvalidInput, match="kept rotation"):
        contact.keep(RigidTransform(RotationMatrix(matrix), [0.0, 0.0, 0.0]))
    assert contact.settings().kept is before
    turned = RotationMatrix.MakeXRotation(0.3).matrix()
    contact.keep(RigidTransform(RotationMatrix(turned + 1e-9), [0.1, 0.0, 0.0]))  # (a rotation to round-off)
    np.testing.assert_allclose(contact.settings().kept[0], turned, atol=1e-8)


# --- friction_ratio ----------------------------------------------------------------------------
@pytest.mark.parametrize("force", [[0.0, 0.0, -100.0], [5.0, 0.0, -100.0], [0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
def test_the_friction_ratio_of_a_force_that_does_not_press_is_infinite(force):
    assert friction_ratio(np.array(force), np.array([0.0, 0.0, 1.0]), 0.8) == math.inf
    assert friction_ratio(np.array([0.8, 0.0, 10.0]), np.array([0.0, 0.0, 1.0]), 0.8) == pytest.approx(0.1)


# --- previous_loads --------------------------------------------------------------------------
def test_previous_loads_names_an_unknown_contact(built):
    robot, diagram, _ = built
    context = diagram.CreateDefaultContext()
    with pytest.raises(ContactNotFound, match=r"contactXX.*contactLF") as error:
        robot.sot.previous_loads(context, ["contactLF", "contactXX"])
    assert isinstance(error.value, NotFound)
    with pytest.raises(InvalidInput, match="names"):
        robot.sot.previous_loads(context, "contactLF")  # type: ignore[arg-type]
    assert robot.sot.previous_loads(context, ["contactLF"]) is None  # (no tick yet: not held then)


# --- an infinite reference ------------------------------------------------------------------
@pytest.mark.parametrize("value", [INF, -INF, NAN])
def test_a_non_finite_reference_acceleration_names_the_task(built, value):
    robot, diagram, com = built
    context = diagram.CreateDefaultContext()
    com.task.GetInputPort("reference_acceleration").FixValue(com.task.GetMyContextFromRoot(context), [value, 0.0, 0.0])
    with pytest.raises(SolverError, match=f"task {com.task.name}"):
        robot.sot.GetOutputPort("control").Eval(robot.sot.GetMyContextFromRoot(context))


def test_a_finite_reference_acceleration_is_solved(built):
    robot, diagram, com = built
    context = diagram.CreateDefaultContext()
    com.task.GetInputPort("reference_acceleration").FixValue(com.task.GetMyContextFromRoot(context), [0.01, 0.0, 0.0])
    assert np.isfinite(robot.sot.GetOutputPort("control").Eval(robot.sot.GetMyContextFromRoot(context))).all()


# --- hand-wired entities with an input left unconnected ----------------------------------------
def _hand_wired(model, forget: str):
    builder = DiagramBuilder()
    dynamic = builder.AddSystem(DynamicEntity(model, "dynamic"))
    sot = builder.AddSystem(SolverDyn("sot", model, 1e-3))
    device = builder.AddSystem(RobotDynSimu(model.plant, 1e-3, model.half_sitting))
    contact = builder.AddSystem(Contact6d("contactLF", model.nv, SOLE, dt=1e-3))
    dynamic.createOpPoint("contactLF", "left-sole")
    port = sot.declare_contact_input(contact)
    if forget != "dynamics":
        builder.Connect(dynamic.GetOutputPort("dynamics"), sot.GetInputPort("dynamics"))
    if forget != "contactLF":
        builder.Connect(contact.GetOutputPort("contact"), port)
    if forget != "kinematics":
        builder.Connect(dynamic.kinematics_port("contactLF"), contact.GetInputPort("kinematics"))
    builder.Connect(sot.GetOutputPort("control"), device.GetInputPort("control"))
    builder.Connect(device.GetOutputPort("state"), dynamic.GetInputPort("state"))
    sot.addContact("contactLF")
    return sot, builder.Build()


@pytest.mark.parametrize(("forget", "named"), [("dynamics", r"sot: its input 'dynamics' is not connected"),
                                               ("contactLF", r"sot: the input 'contactLF' of the contact 'contactLF'"),
                                               ("kinematics", r"contact 'contactLF': its input 'kinematics'")])
def test_an_unconnected_input_names_the_entity_the_port_and_what_to_connect(talos_model, forget, named):
    sot, diagram = _hand_wired(talos_model, forget)
    context = diagram.CreateDefaultContext()
    with pytest.raises(StackError, match=named) as error:
        sot.GetOutputPort("torque").Eval(sot.GetMyContextFromRoot(context))
    assert "builder.Connect(" in str(error.value)


def test_the_same_entities_wired_in_full_are_solved(talos_model):
    sot, diagram = _hand_wired(talos_model, "nothing")
    torque = sot.GetOutputPort("torque").Eval(sot.GetMyContextFromRoot(diagram.CreateDefaultContext()))
    assert np.isfinite(torque).all() and np.abs(torque).max() > 0


# --- trajectories, op points, configurations -------------------------------------------------
@pytest.mark.parametrize(("call", "named"), [
    (lambda: minimum_jerk_moves(np.zeros(3), [(0.0, 1e-300, np.ones(3))]), "t1"),
    (lambda: hold_move_hold(0.0, 1e-17, np.zeros(3), np.ones(3)), "t1"),
    (lambda: hold_move_hold(0.5, 0.5 + 1e-9, np.zeros(1), np.ones(1)), "t1"),
    (lambda: minimum_jerk_moves(np.zeros(1), [(1e-20, 1.0, np.ones(1))]), "t0"),
    (lambda: minimum_jerk_moves(np.zeros(1), [(0.0, 1.0, np.ones(1)), (1.0 + 1e-12, 2.0, np.zeros(1))]), "t0"),
    (lambda: minimum_jerk_moves(np.zeros(1), [(0.0, 1e-3, np.ones(1))], end=1e-3 + 1e-18), "end"),
])
def test_moves_too_short_for_a_spline_are_refused_before_drake_sees_them(call, named):
    with pytest.raises(InvalidInput, match=named):
        call()


def test_the_shortest_move_and_hold_are_accepted():
    from sotdrake.dynamics.trajectories import MIN_MOVE

    trajectory = minimum_jerk_moves(np.zeros(1), [(0.3, 0.3 + MIN_MOVE, np.ones(1)), (0.3 + 2 * MIN_MOVE, 0.5, np.zeros(1))],
                                    end=0.5 + MIN_MOVE, samples=10_000)
    assert trajectory.end_time() == 0.5 + MIN_MOVE and trajectory.value(0.3 + MIN_MOVE)[0, 0] == pytest.approx(1.0)
    ends = minimum_jerk_moves(np.zeros(1), [(0.1, 0.3, np.ones(1))], end=0.3)  # (the move ends at t1 exactly)
    assert ends.end_time() == 0.3 and ends.value(0.3)[0, 0] == pytest.approx(1.0)


@pytest.mark.parametrize("name", [None, "", 3])
def test_trajectory_ports_names_a_bad_name(talos_model, name):
    builder = DiagramBuilder()
    robot = RobotDyn(builder, talos_model, "dynsimu")
    systems = len(builder.GetSystems())
    with pytest.raises(InvalidInput, match="name"):
        trajectory_ports(robot, hold_move_hold(0.0, 1.0, np.zeros(3), np.ones(3)), name)
    assert len(builder.GetSystems()) == systems
    trajectory_ports(robot, hold_move_hold(0.0, 1.0, np.zeros(3), np.ones(3)), "t")
    assert len(builder.GetSystems()) == systems + 2


def test_trajectory_ports_refuses_what_is_not_a_robot():
    with pytest.raises(InvalidInput, match="robot"):
        trajectory_ports(DiagramBuilder(), hold_move_hold(0.0, 1.0, np.zeros(3), np.ones(3)), "t")  # type: ignore[arg-type]


@pytest.mark.parametrize("port", ["kinematics_port", "drift_port"])
def test_an_op_point_port_of_an_unknown_op_point_lists_the_known_ones(dyn, port):
    robot, _, _ = dyn
    with pytest.raises(NotFound, match=f"{port}.*'nope'.*'contactLF'"):
        getattr(robot.dynamic, port)("nope")
    with pytest.raises(InvalidInput, match="name"):
        getattr(robot.dynamic, port)(None)
    assert getattr(robot.dynamic, port)("contactLF").get_name().startswith("contactLF_")


def test_a_trajectory_through_a_configuration_with_no_base_rotation_names_its_row(dyn):
    robot, _, _ = dyn
    qs = np.tile(robot.q0, (3, 1))
    qs[1, :4] = 0.0
    with pytest.raises(InvalidInput, match=r"qs\[1\].*quaternion"):
        robot.dynamic.trajectory(["contactLF"], qs)
    with pytest.raises(InvalidInput, match="quaternion"):
        robot.dynamic.pose_at("contactLF", qs[1])  # (the same rule, one configuration)
    path = robot.dynamic.trajectory(["contactLF"], np.tile(robot.q0, (2, 1)))
    assert path["contactLF"].shape == (2, 4, 4)


# --- the tutorial's snippet --------------------------------------------------------------------
def _snippet() -> str:
    page = (ROOT / "docs" / "tutorials" / "dynamic_sot.md").read_text()
    section = page.split("## What the script does", 1)[1].split("\n## ", 1)[0]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)  # type: ignore[union-attr]


def test_the_tutorials_snippet_puts_the_foot_task_above_the_posture_as_the_script_does(monkeypatch):
    """The snippet's release command, run as its ``attime`` would run it: the foot task ends above the
    posture, as in the script (below it, the posture task, which takes every joint, leaves the foot
    nothing), and the right contact is released."""
    commands = []
    monkeypatch.setattr(sotdrake, "attime", lambda time, command, description="": commands.append((time, command)))
    namespace: dict = {}
    exec(compile(_snippet().replace('device="physics"', 'device="dynsimu"'), "dynamic_sot.md", "exec"), namespace)
    robot = namespace["robot"]
    (time, release), = [(t, c) for t, c in commands if "rmContact" in c.__code__.co_names]
    release()
    stack = robot.sot.stack()
    assert stack.index(namespace["taskRF"].task.name) < stack.index("taskposture"), stack
    assert robot.sot.settings().releasing == {"contactRF": 0.3} and time == 2.2


# --- the scenarios' soles on the exactly integrating device ----------------------------------
def test_the_scenarios_hold_the_soles_through_the_squat_on_dynsimu():
    """``talos_dynamics`` on ``dynsimu`` (no ground: only the contact rows hold the soles): through the
    squat's first second (halfway down) the held soles move by less than 0.02 mm (0.038 mm
    with velocity damping alone, 0.18 mm over the whole squat)."""
    from sotdrake.scenarios import talos_dynamics
    from sotdrake.scenarios.common import translation_drift

    run = talos_dynamics.build_diagram("squat", "dynsimu")
    simulator, _ = talos_dynamics.simulate_ticks(run, 1.0, progress=False)
    trace = run.tracer.data(simulator.get_context())
    path = run.robot.dynamic.trajectory(["contactLF", "contactRF"], trace["x"][:, : run.robot.model.nq])
    assert path["com"][0, 2] - path["com"][-1, 2] > 0.05  # (it squats)
    assert max(translation_drift(path[sole]).max() for sole in ("contactLF", "contactRF")) < 2e-5
