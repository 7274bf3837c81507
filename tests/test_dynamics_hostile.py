"""The dynamic SoT under hostile inputs and random cases.

Bad inputs at every public entry point (commands, constructors, the CLI of ``talos_dynamics``):
a :class:`~sotdrake.exceptions.SotError` naming the argument, and nothing changed (every entity's
settings in the Context and in its defaults, every discrete state). Random dynamic stacks at random
valid states, through ``SolverDyn`` itself (its fast path, QR path and hierarchical QP): Drake's
forward dynamics reproduce ``q̈`` from ``τ`` and the contact wrenches, the contacts do not
accelerate, the wrench rows, ``f_min``, torque and joint-limit bounds hold, and a lower task never
changes a higher level's slack.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.systems.framework import DiagramBuilder

from sotdrake import TALOS_GRIPPERS
from sotdrake.dynamics.checks import check_pd_gains
from sotdrake.dynamics.contact import Contact6d
from sotdrake.dynamics.device import RobotDynSimu
from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynPosture
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.dynamics.solver_dyn import SolverDyn
from sotdrake.dynamics.task_dyn_pd import TaskDynPD
from sotdrake.dynamics.terms import acceleration_bounds
from sotdrake.entity import Entity
from sotdrake.exceptions import FrameNotFound, InvalidInput, NotFound, SotError
from sotdrake.robots import load_talos
from tests.conftest import random_configuration
from tests.hostile import _plain

ROOT = Path(__file__).resolve().parents[1]
NAN, INF = float("nan"), float("inf")
#: What a number argument must refuse whatever its range (cf. tests/hostile.py's BAD_NUMBERS).
NOT_NUMBERS = ["1.0", None, [1.0], True, complex(1, 1), np.array([1.0, 2.0])]
NON_FINITE = [NAN, INF, -INF, 1e300]
SOLES = {"contactLF": "left_sole_link", "contactRF": "right_sole_link"}


def _build_dyn():
    """A dynsimu diagram: both soles held, the CoM and the posture in the stack; the right foot's
    and both wrists' 6D tasks declared (not pushed)."""
    model = load_talos("reduced")
    builder = DiagramBuilder()
    robot = RobotDyn(builder, model, "dynsimu")
    lf, rf = robot.add_contact("contactLF", "left-sole"), robot.add_contact("contactRF", "right-sole")
    tasks = {"com": MetaTaskDynCom(robot), "posture": MetaTaskDynPosture(robot),
             "RF": MetaTaskDyn6d("RF", robot, "right-foot", "right-sole"),
             "rh": MetaTaskDyn6d("rh", robot, "rh", "right-wrist"), "lh": MetaTaskDyn6d("lh", robot, "lh", "left-wrist")}
    robot.sot.addContact(lf)
    robot.sot.addContact(rf)
    robot.sot.push(tasks["com"].task.name)
    robot.sot.push(tasks["posture"].task.name)
    diagram = builder.Build()
    return robot, diagram, tasks


@pytest.fixture(scope="module")
def dyn():
    return _build_dyn()


def fingerprint(diagram, context) -> str:
    """Every entity's settings (context and defaults) and every discrete state."""
    image = {}
    for system in diagram.GetSystems():
        own = system.GetMyContextFromRoot(context)
        entry = {"discrete": [own.get_discrete_state(i).get_value().tolist() for i in range(own.num_discrete_state_groups())]}
        if isinstance(system, Entity):
            entry["settings"] = _plain(system.settings(context))
            entry["defaults"] = _plain(system.settings())
        image[system.get_name()] = entry
    return json.dumps(image, sort_keys=True, default=repr)


# --- commands: a SotError naming the argument, nothing changed ----------------------------------
def _commands(robot, tasks):
    """``(label, call(value, context), what the message names, values refused)`` of each command."""
    sot, lf, com = robot.sot, robot.contacts["contactLF"], tasks["com"].task
    return [
        ("setFriction", lambda v, c: lf.setFriction(v, c), "μ", [0.0, -0.5, 11.0]),
        ("setMinimumNormalForce", lambda v, c: lf.setMinimumNormalForce(v, c), "f_min", [-1.0, 2e4]),
        ("setCopMargin", lambda v, c: lf.setCopMargin(v, c), "CoP margin", [-1e-3, 0.5]),
        ("setVelocityGain", lambda v, c: lf.setVelocityGain(v, c), "K_v", [-1.0, 1e4]),
        ("setPositionGain", lambda v, c: lf.setPositionGain(v, c), "K_p", [-1.0, 3e5]),
        ("setDampingGain", lambda v, c: sot.setDampingGain(v, c), "K_d", [-1.0, 1e4]),
        ("setJointLimitHorizon", lambda v, c: sot.setJointLimitHorizon(v, context=c), "horizon", [0.0, -0.05, 100.0]),
        ("setJointLimitHorizon(margin)", lambda v, c: sot.setJointLimitHorizon(0.05, v, c), "margin", [-1e-3, 1.0]),
        ("rmContact(duration)", lambda v, c: sot.rmContact("contactRF", v, c), "duration", [-1.0, 1e3]),
        ("setGain(Kp)", lambda v, c: com.setGain(v, context=c), "Kp", [-1.0, 1e7]),
        ("setGain(Kp, Kv)", lambda v, c: com.setGain(100.0, v, c), "Kv", [-1.0, 1e7]),  # (Kv None: 2√Kp)
        ("setKp", lambda v, c: com.setKp(v, c), "Kp", [-1.0, 1e7]),
        ("setKv", lambda v, c: com.setKv(v, c), "Kv", [-1.0, 1e7]),
    ]


COMMANDS = ["setFriction", "setMinimumNormalForce", "setCopMargin", "setVelocityGain", "setPositionGain", "setDampingGain",
            "setJointLimitHorizon",
            "setJointLimitHorizon(margin)", "rmContact(duration)", "setGain(Kp)", "setGain(Kp, Kv)", "setKp", "setKv"]


@pytest.mark.parametrize("command", COMMANDS)
def test_a_bad_number_is_refused_by_name_and_changes_nothing(dyn, command):
    robot, diagram, tasks = dyn
    context = diagram.CreateDefaultContext()
    _, call, named, out_of_range = next(entry for entry in _commands(robot, tasks) if entry[0] == command)
    before = fingerprint(diagram, context)
    for value in [*NOT_NUMBERS, *NON_FINITE, *out_of_range]:
        if command == "setGain(Kp, Kv)" and value is None:
            continue  # the critical damping, documented
        with pytest.raises(InvalidInput, match=named):
            call(value, context)
        assert fingerprint(diagram, context) == before, f"{command}({value!r}) changed the context"


def test_unstable_pd_gains_are_refused(dyn):
    """At the control tick (1 ms) K_p dt² + 2 K_v dt ≥ 4 diverges; such gains are refused."""
    robot, diagram, tasks = dyn
    context = diagram.CreateDefaultContext()
    before = fingerprint(diagram, context)
    for kp, kv in ((4e6, 0.0), (0.0, 2000.0), (1e6, None), (3e6, 600.0)):
        with pytest.raises(InvalidInput, match="unstable"):
            tasks["com"].task.setGain(kp, kv, context)
    assert fingerprint(diagram, context) == before
    tasks["com"].task.setGain(3e6, 400.0, context)  # 3 + 0.8 < 4: accepted
    assert (tasks["com"].task.settings(context).kp, tasks["com"].task.settings(context).kv) == (3e6, 400.0)


def test_the_stability_bound_of_the_pd_gains_is_exact():
    """``check_pd_gains`` accepts exactly the gains whose error recurrence (the device's
    semi-implicit Euler step, ``ė ← ė + (−K_p e − K_v ė) dt``, ``e ← e + ė dt``) has no root
    outside the unit circle."""
    rng = np.random.default_rng(5)
    dt = 1e-3
    accepted = refused = 0
    for _ in range(400):
        kp, kv = rng.uniform(0, 6e6), rng.uniform(0, 2500)
        step = np.array([[1 - kp * dt**2, dt * (1 - kv * dt)], [-kp * dt, 1 - kv * dt]])  # (e, ė) ← step (e, ė)
        radius = np.abs(np.linalg.eigvals(step)).max()
        try:
            check_pd_gains("t", kp, kv, dt)
        except InvalidInput:
            refused += 1
            assert radius > 1 - 1e-9
        else:
            accepted += 1
            assert radius <= 1 + 1e-9
    assert accepted > 50 and refused > 50


def test_stack_and_contact_commands_refuse_unknown_names(dyn):
    robot, diagram, tasks = dyn
    sot = robot.sot
    context = diagram.CreateDefaultContext()
    before = fingerprint(diagram, context)
    for name in ["contactXX", None, 5, ["contactLF"], tasks["com"].task.name]:
        for call in (lambda n: sot.addContact(n, context), lambda n: sot.rmContact(n, context=context)):
            with pytest.raises(NotFound):
                call(name)
    for name in ["taskXX", None, "contactLF", ["taskcom"]]:
        for call in (sot.push, sot.remove, sot.up, sot.down):
            with pytest.raises(SotError):
                call(name, context)
    with pytest.raises(InvalidInput, match="solver"):
        sot.setSolver("nope", context)
    assert fingerprint(diagram, context) == before


def test_kinematic_settings_are_refused_not_ignored(dyn):
    """SolverDyn has no SVD threshold, no damped least squares and no velocity scaling: the
    kinematic SOT's setters raise instead of storing a setting nothing reads."""
    robot, diagram, _ = dyn
    sot = robot.sot
    context = diagram.CreateDefaultContext()
    before = fingerprint(diagram, context)
    for call in (lambda: sot.setThreshold(0.5, context), lambda: sot.setDamping(1e3, context),
                 lambda: sot.setVelocityLimit(np.full(robot.model.nv, 1e-3), context), lambda: sot.setDamping(0.1)):
        with pytest.raises(SotError, match="SolverDyn"):
            call()
    assert fingerprint(diagram, context) == before


def test_a_contact_removed_twice_and_the_last_contact_are_refused(dyn):
    robot, diagram, _ = dyn
    sot = robot.sot
    context = diagram.CreateDefaultContext()
    sot.rmContact("contactRF", 0.0, context)
    before = fingerprint(diagram, context)
    for duration in (0.0, 0.3):
        with pytest.raises(SotError, match="contactRF"):
            sot.rmContact("contactRF", duration, context)
        with pytest.raises(SotError, match="last contact"):
            sot.rmContact("contactLF", duration, context)
    assert fingerprint(diagram, context) == before
    assert sot.held_contacts(context) == ["contactLF"]


def test_a_context_of_another_diagram_is_refused(dyn):
    robot, diagram, tasks = dyn
    context = diagram.CreateDefaultContext()
    other = RobotDyn(DiagramBuilder(), robot.model, "dynsimu")
    other_context = other.builder.Build().CreateDefaultContext()
    sot, lf, com = robot.sot, robot.contacts["contactLF"], tasks["com"].task
    before = fingerprint(diagram, context)
    for wrong in (other_context, other.sot.GetMyContextFromRoot(other_context), "context", 3):
        for call in (lambda c: sot.setDampingGain(1.0, c), lambda c: lf.setFriction(0.5, c), lambda c: com.setGain(4.0, context=c),
                     lambda c: sot.rmContact("contactRF", 0.1, c), lambda c: sot.push(tasks["rh"].task.name, c),
                     lambda c: sot.held_contacts(c)):
            with pytest.raises(InvalidInput, match="context"):
                call(wrong)
    assert fingerprint(diagram, context) == before


# --- constructors ----------------------------------------------------------------------------------
def test_constructors_refuse_bad_arguments_by_name(talos_model):
    model, nv = talos_model, talos_model.nv
    sole = (-0.1, 0.1, -0.05, 0.05)
    cases = [
        *[(lambda v=v: Contact6d("c", nv, v), "rectangle") for v in
          [(-INF, INF, -0.05, 0.05), (NAN, 0.1, -0.05, 0.05), (0, 1, 0), "abcd", 5, (-1e300, 1e300, -1, 1), (0.1, 0.1, 0, 1)]],
        *[(lambda v=v: Contact6d("c", nv, sole, mu=v), "μ") for v in [*NOT_NUMBERS, *NON_FINITE, 0.0]],
        *[(lambda v=v: Contact6d("c", nv, sole, f_min=v), "f_min") for v in [*NOT_NUMBERS, NAN, -1.0]],
        *[(lambda v=v: Contact6d("c", v, sole), "nv") for v in [-1, 0, 1.5, "38", None, True]],
        *[(lambda v=v: TaskDynPD("t", nv, v), "dt") for v in [*NOT_NUMBERS, *NON_FINITE, 0.0, -1e-3]],
        *[(lambda v=v: TaskDynPD("t", nv, 1e-3, dimension=v), "dimension") for v in [-1, 0, 1.5, "3", nv + 1]],
        *[(lambda v=v: TaskDynPD("t", nv, 1e-3, kp=v), "Kp") for v in [*NOT_NUMBERS, *NON_FINITE, -1.0]],
        *[(lambda v=v: SolverDyn("s", model, v), "dt") for v in [*NOT_NUMBERS, *NON_FINITE, 0.0, -1e-3]],
        *[(lambda v=v: SolverDyn("s", model, 1e-3, max_contacts=v), "max_contacts") for v in [0, -1, 1.5, "2", None, True, 10**6]],
        *[(lambda v=v: SolverDyn("s", model, 1e-3, damping_gain=v), "K_d") for v in [*NOT_NUMBERS, *NON_FINITE, -1.0]],
        *[(lambda v=v: RobotDyn(DiagramBuilder(), model, "dynsimu", dt=v), "dt") for v in [NAN, 0.0, "x", INF, 1e-7]],
        (lambda: RobotDynSimu(model.plant, 1e-3, np.r_[np.zeros(4), model.half_sitting[4:]]), "quaternion"),
    ]
    for device in ("dynsimu", "physics"):  # physics: Drake aborted the process on these q0
        for q0 in (np.full(model.nq, NAN), np.ones(3), "abc", np.r_[np.zeros(4), model.half_sitting[4:]]):
            cases.append((lambda d=device, q=q0: RobotDyn(DiagramBuilder(), model, d, q0=q), "q0"))
    for call, named in cases:
        with pytest.raises(InvalidInput, match=named):
            call()
    assert SolverDyn("s", model, 1e-3, effort_scale=np.float32(0.5)).effort_scale == 0.5  # any real number type


def test_a_refused_task_or_contact_leaves_the_builder_usable(talos_model):
    """A meta task with a bad gain, or a contact on an unknown op point, adds nothing: the same
    names can be used again."""
    robot = RobotDyn(DiagramBuilder(), talos_model, "dynsimu")
    systems = len(robot.builder.GetSystems())
    for kp in (-1.0, NAN, "x", 1e7):
        with pytest.raises(InvalidInput, match="Kp"):
            MetaTaskDyn6d("x", robot, "x", "right-wrist", kp=kp)
        with pytest.raises(InvalidInput, match="Kp"):
            MetaTaskDynCom(robot, kp=kp)
        with pytest.raises(InvalidInput, match="Kp"):
            MetaTaskDynPosture(robot, kp=kp)
    for op_point in ("nope", None, 5):
        with pytest.raises(FrameNotFound):
            robot.add_contact("contactLF", op_point)
    assert len(robot.builder.GetSystems()) == systems
    MetaTaskDyn6d("x", robot, "x", "right-wrist")
    MetaTaskDynCom(robot)
    MetaTaskDynPosture(robot)
    robot.add_contact("contactLF", "left-sole")
    robot.add_contact("contactRF", "right-sole")
    systems = len(robot.builder.GetSystems())
    with pytest.raises(InvalidInput, match="max_contacts"):  # built for 2
        robot.add_contact("contactRH", "right-wrist", rectangle=None)
    assert len(robot.builder.GetSystems()) == systems


# --- the script's command line ---------------------------------------------------------------------
@pytest.fixture(scope="module")
def dynamics_script():
    from sotdrake.scenarios import talos_dynamics

    return talos_dynamics


def test_the_scripts_bad_arguments_stop_before_the_run(dynamics_script, tmp_path, capsys):
    """Refused before anything is built or simulated: argparse's usage error (exit code 2), or
    ``start``'s message (exit code 1); never a traceback."""
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    common = ["--scenario", "stand", "--device", "dynsimu", "--no-meshcat", "--quiet", "--duration", "0.01"]
    for argv, code, message in [
        (["--scenario", "nope"], 2, "--scenario"), (["--device", "nope"], 2, "--device"),
        (["--effort-scale", "2"], 2, "--effort-scale"), (["--effort-scale", "nan"], 2, "--effort-scale"),
        (["--effort-scale", "0"], 2, "--effort-scale"), (["--duration", "abc"], 2, "--duration"),
        (["--duration", "-1"], None, "--duration"), (["--duration", "nan"], None, "--duration"),
        (["--duration", "inf"], None, "--duration"), (["--duration", "1e300"], None, "--duration"),  # would never end
        (["--out", str(blocker / "run")], None, "--out"),  # the run would be lost at its end
    ]:
        with pytest.raises(SystemExit) as stop:
            dynamics_script.main(common + ["--out", str(tmp_path / "out")] + argv)
        if code is None:
            assert message in str(stop.value.code)
        else:
            assert stop.value.code == code and message in capsys.readouterr().err
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_the_scripts_exit_code_and_message_without_traceback(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for argv, code in ((["--effort-scale", "1.5"], 2), (["--out", str(blocker / "run")], 2)):
        run = subprocess.run([sys.executable, str(ROOT / "diagrams" / "talos_dynamics.py"), "--no-meshcat", "--quiet",
                              "--device", "dynsimu", "--duration", "0.01", *argv], capture_output=True, text=True, cwd=ROOT,
                             env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=600)
        assert run.returncode == code and "Traceback" not in run.stderr and argv[0] in run.stderr


# --- random dynamic stacks at random valid states, through SolverDyn itself -----------------------
def random_case(robot, tasks, seed: int, project: bool = True):
    """A random case: ``(x, stack, contacts, settings)`` with ``x = (q, v)`` valid: joints at least
    1 % of their range inside their limits, joint velocities within half their limits and, with
    ``project``, ``v`` in the null space of the held soles' Jacobians (the soles do not move);
    ``settings(context)`` applies random contact settings (μ, f_min, CoP margin), random gains to
    every task, random targets (CoM ± 5 cm, hands and right foot ± 10 cm) and possibly the
    grippers' control selection."""
    from pydrake.multibody.tree import JacobianWrtVariable

    model, sot = robot.model, robot.sot
    rng = np.random.default_rng(seed)
    names = list(rng.permutation(list(tasks))[: rng.integers(0, 6)])
    contacts = ["contactLF", "contactRF"] if rng.random() < 0.6 else [["contactLF"], ["contactRF"]][rng.integers(2)]
    selection = rng.random() < 0.5
    spread = float(rng.choice([0.0, 0.05, 0.2]))
    q = random_configuration(model, rng, spread) if spread else model.half_sitting.copy()
    v = rng.normal(scale=[0.0, 0.2, 0.5][int(rng.integers(3))], size=model.nv)
    iq, iv = sot.layout.joints_q, sot.layout.joints_v
    lower, upper = sot._limits[0][iq], sot._limits[1][iq]
    q[iq] = np.clip(q[iq], lower + 0.01 * (upper - lower), upper - 0.01 * (upper - lower))
    v[iv] = np.clip(v[iv], 0.5 * sot._limits[2][iv], 0.5 * sot._limits[3][iv])
    if project:
        plant = model.plant
        plant_context = plant.CreateDefaultContext()
        plant.SetPositions(plant_context, q)
        J = np.vstack([plant.CalcJacobianSpatialVelocity(plant_context, JacobianWrtVariable.kV, plant.GetFrameByName(SOLES[c]),
                                                         np.zeros(3), plant.world_frame(), plant.world_frame()) for c in contacts])
        v = v - np.linalg.pinv(J) @ (J @ v)

    def settings(context, stack):
        draw = np.random.default_rng(seed)
        for name in list(sot.stack(context)):
            sot.remove(name, context)
        for name in ("contactLF", "contactRF"):
            if name not in contacts:
                sot.rmContact(name, 0.0, context)
        for name in stack:
            sot.push(tasks[name].task.name, context)
        for name in ("contactLF", "contactRF"):
            contact = robot.contacts[name]
            contact.setFriction(float(draw.uniform(0.2, 1.2)), context)
            contact.setMinimumNormalForce(float(draw.uniform(0, 50)), context)
            contact.setCopMargin(float(draw.uniform(0, 0.03)), context)
        for task in tasks.values():
            task.task.setGain(float(draw.uniform(1, 400)), context=context)
        tasks["com"].featureDes.setReference(tasks["com"].initial_com() + draw.uniform(-0.05, 0.05, 3), context)
        for name in ("rh", "lh", "RF"):
            X = tasks[name].initial_pose()
            tasks[name].featureDes.setPosition(RigidTransform(X.rotation(), X.translation() + draw.uniform(-0.1, 0.1, 3)), context)
        if selection:
            sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS), context)

    return np.concatenate([q, v]), names, contacts, settings


def solve_case(robot, diagram, x, settings, stack):
    context = diagram.CreateDefaultContext()
    robot.device.GetMyContextFromRoot(context).SetDiscreteState(x)
    settings(context, stack)
    sot_context = robot.sot.GetMyContextFromRoot(context)
    return context, sot_context, robot.sot._solution.Eval(sot_context)


def forward_acceleration(model, x, torque, wrenches) -> np.ndarray:
    """Drake's forward dynamics of the plant driven by ``torque`` with the world contact wrenches
    ``(n, f)`` applied at the soles."""
    plant = model.plant
    context = plant.CreateDefaultContext()
    plant.SetPositionsAndVelocities(context, x)
    plant.get_actuation_input_port().FixValue(context, torque)
    forces = []
    for name, W in wrenches.items():
        frame = plant.GetFrameByName(SOLES[name])
        force = ExternallyAppliedSpatialForce()
        force.body_index = frame.body().index()
        force.p_BoBq_B = frame.GetFixedPoseInBodyFrame().translation()
        force.F_Bq_W = SpatialForce(W[:3], W[3:])
        forces.append(force)
    plant.get_applied_spatial_force_input_port().FixValue(context, forces)
    return plant.EvalTimeDerivatives(context).get_vector().CopyToVector()[model.nq :]


@pytest.mark.parametrize("seed", [3000, 3001, 3002, 3003, 3005, 3007, 3012, 3018, 3080, 3093])
def test_random_stacks_at_random_valid_states(dyn, seed):
    """Through SolverDyn (its fast path, QR path, hierarchical QP): τ reproduces q̈ through Drake's
    forward dynamics (a plant of its own, the contact wrenches applied), the held soles do not
    accelerate, their wrench rows and f_min hold, |τ| ≤ the effort limits, q̈ within the
    joint-limit acceleration bounds, and every level keeps its slack when the tasks below it are
    removed (strict priority)."""
    robot, diagram, tasks = dyn
    sot = robot.sot
    x, names, contacts, settings = random_case(robot, tasks, seed)
    context, sot_context, solution = solve_case(robot, diagram, x, settings, names)
    assert not solution.diagnostics.failure
    v_dot = forward_acceleration(load_talos("reduced"), x, solution.torque, solution.wrenches)
    np.testing.assert_allclose(v_dot, solution.acceleration, atol=1e-6 * max(1.0, np.abs(v_dot).max()))
    assert np.all(np.abs(solution.torque) <= sot.effort * (1 + 1e-9))
    terms = sot.dynamics.Eval(sot_context)
    a_lower, a_upper = acceleration_bounds(terms.q, terms.v, *sot._limits, 0.05, 1e-3, sot.layout, dt=sot.dt)
    fixed = sot.settings(context).control_selection
    if fixed is not None:
        a_lower[~fixed] = a_upper[~fixed] = 0.0
    slack = 1e-7 * max(1.0, np.abs(solution.acceleration).max())
    assert np.all(solution.acceleration >= a_lower - slack) and np.all(solution.acceleration <= a_upper + slack)
    assert sorted(solution.local_wrenches) == sorted(contacts)
    for name in contacts:
        contact = robot.contacts[name]
        rows = contact.GetOutputPort("contact").Eval(contact.GetMyContextFromRoot(context))
        w = solution.local_wrenches[name]
        assert np.all(rows.wrench_rows @ w <= 1e-6 * np.abs(w).max()) and w[5] >= rows.f_min - 1e-9
        np.testing.assert_allclose(rows.jacobian @ solution.acceleration, rows.acceleration,
                                   atol=1e-6 * max(1.0, np.abs(rows.acceleration).max()))
    for k in range(len(names)):  # the stack truncated to its k first tasks
        truncated = solve_case(robot, diagram, x, settings, names[:k])[2]
        assert not truncated.diagnostics.failure
        common = 2 + k  # dynamics, contacts, the k first tasks
        np.testing.assert_allclose(solution.residuals[:common], truncated.residuals[:common], rtol=1e-6, atol=1e-6)


def test_a_degenerate_vertex_on_the_last_level_is_solved():
    """At this valid state (half-sitting, the grippers 1 % inside their limits, sole-consistent
    velocities; stack rh, com) the last (damping) level's optimum sits where bounds meet nearly
    dependent at the same value: with the working set's rank decisions at τ every path ended 2e-8
    beyond a bound (the 1e-9 check refused it, and SolverDyn dropped the stack for the tick). The
    retry with a finer working set (hqp.DEGENERATE_RETRY) solves it."""
    robot, diagram, tasks = _build_dyn()
    x, names, _, settings = random_case(robot, tasks, 3093)
    assert names == ["rh", "com"]
    solution = solve_case(robot, diagram, x, settings, names)[2]
    assert not solution.diagnostics.failure, solution.diagnostics.failure


def test_a_solution_does_not_depend_on_the_cases_solved_before():
    """A case solved right after another one of the same sizes (the solver's warm starts) gives the
    answer of a fresh solver (it failed, at a degenerate vertex of the last level, before the
    retry of hqp.DEGENERATE_RETRY)."""
    stack = ["com", "rh"]
    robot, diagram, tasks = _build_dyn()
    fresh = solve_case(robot, diagram, *random_case(robot, tasks, 2040, project=False)[::3], stack)[2]
    assert not fresh.diagnostics.failure
    robot, diagram, tasks = _build_dyn()
    solve_case(robot, diagram, *random_case(robot, tasks, 2011, project=False)[::3], stack)
    after = solve_case(robot, diagram, *random_case(robot, tasks, 2040, project=False)[::3], stack)[2]
    assert not after.diagnostics.failure, after.diagnostics.failure
    np.testing.assert_allclose(after.acceleration, fresh.acceleration, atol=1e-9)


def test_a_released_contact_leaves_the_contacts_once_its_ramp_has_ended():
    """``rmContact(name, duration)``: the contact is listed while its force ramps down, and no more
    once the ramp has ended (the solver no longer uses it); the defaults list the commanded ones."""
    from pydrake.systems.analysis import Simulator

    robot, diagram, _ = _build_dyn()  # both soles held
    sot = robot.sot
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    simulator.Initialize()
    simulator.AdvanceTo(0.0105)
    sot.rmContact("contactRF", 0.02, context)
    simulator.AdvanceTo(0.0205)
    assert sot.contacts(context) == ["contactLF", "contactRF"]  # ramping down
    simulator.AdvanceTo(0.0405)
    assert sot.contacts(context) == ["contactLF"]
    assert sot.contacts() == ["contactLF", "contactRF"]  # the default context: as commanded


def test_a_sole_rectangle_is_only_given_for_a_sole():
    robot, _, _ = _build_dyn()
    with pytest.raises(SotError, match="no sole rectangle known for talos's 'right-wrist'"):
        robot.add_contact("contactRH", "right-wrist")


def test_a_missed_contact_level_is_warned_once(caplog):
    """At this valid state the soles move (random joint velocities) and the bounds above the contacts
    leave too little to stop them at once: the contacts' level keeps a slack (1.2 m/s² here). The
    solver says so once, in the log, besides its diagnostics."""
    robot, diagram, tasks = _build_dyn()
    x, names, _, settings = random_case(robot, tasks, 4112, project=False)
    with caplog.at_level("WARNING", logger="sotdrake.solver_dyn"):
        solution = solve_case(robot, diagram, x, settings, names)[2]
        solve_case(robot, diagram, x, settings, names)
    assert solution.residuals[1] > 1e-3 and not solution.diagnostics.failure
    warnings = [r for r in caplog.records if "contacts' zero acceleration is missed" in r.getMessage()]
    assert len(warnings) == 1


def test_a_derated_robot_whose_dynamics_cannot_be_met_gets_the_best_dynamics_not_zero_torque(talos_model, caplog):
    """At half the effort limits, this valid state's dynamics cannot be met under the joint-limit and
    selection bounds: the level under it, held at that residual, failed on every path and the solver
    sent zero torque (q̈ = 0). Whatever path answers, the torque is within the limits, not zero, and
    the dynamics residual is the bounded least-squares optimum of the dynamics row alone (scipy's
    BVLS, independent), with a warning that names the dynamics."""
    from scipy.optimize import lsq_linear

    from sotdrake.dynamics.formulation import dynamic_levels

    case = json.loads((Path(__file__).parent / "data" / "derated_dynamics_state.json").read_text())
    builder = DiagramBuilder()
    robot = RobotDyn(builder, talos_model, "dynsimu", effort_scale=case["effort_scale"])
    for name, sole in (("contactLF", "left-sole"), ("contactRF", "right-sole")):
        robot.sot.addContact(robot.add_contact(name, sole))
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    robot.device.GetMyContextFromRoot(context).SetDiscreteState(np.array(case["x"]))
    for name, (mu, f_min, margin) in case["contact_settings"].items():
        contact = robot.contacts[name]
        contact.setFriction(mu, context), contact.setMinimumNormalForce(f_min, context), contact.setCopMargin(margin, context)
    sot = robot.sot
    sot.setDampingGain(case["Kd"], context)
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS), context)
    own = sot.GetMyContextFromRoot(context)
    with caplog.at_level("WARNING", logger="sotdrake.solver_dyn"):
        solution = sot._solution.Eval(own)
    problem = sot._problem(own, sot.settings(context))
    dynamics = dynamic_levels(problem.terms, problem.contacts, [], case["Kd"])[0][0]
    fixed = problem.lower == problem.upper  # (the grippers' q̈ = 0: BVLS takes only open boxes)
    b = dynamics.lower - dynamics.A[:, fixed] @ problem.lower[fixed]
    best = lsq_linear(dynamics.A[:, ~fixed], b, bounds=(problem.lower[~fixed], problem.upper[~fixed]), method="bvls", tol=1e-12)
    optimum = float(np.linalg.norm(dynamics.A[:, ~fixed] @ best.x - b))
    assert optimum > 1e-3  # (the case: the dynamics cannot be met)
    assert np.abs(solution.torque).max() > 1.0 and np.all(np.abs(solution.torque) <= sot.effort * (1 + 1e-9))
    assert solution.residuals[0] <= optimum * (1 + 1e-6) + 1e-9
    assert any("the dynamics is missed" in record.message for record in caplog.records)


def test_solver_dyn_and_add_task_refuse_what_they_cannot_use(talos_model):
    for name, model in (("", talos_model), (None, talos_model), ("s", None), ("s", "talos")):
        with pytest.raises(InvalidInput):
            SolverDyn(name, model, 1e-3)  # type: ignore[arg-type]
    builder = DiagramBuilder()
    robot = RobotDyn(builder, talos_model, "dynsimu")
    for horizon in (1e-200, 0.0, 11.0):
        with pytest.raises(InvalidInput, match="horizon"):
            robot.sot.setJointLimitHorizon(horizon)
    systems = len(builder.GetSystems())
    for task in (TaskDynPD("taskfast", talos_model.nv, 1e-4, kp=4.5e6, kv=0.0), TaskDynPD("tasksmall", 10, 1e-3), "task"):
        with pytest.raises(InvalidInput, match="add_task"):
            robot.add_task(task)  # type: ignore[arg-type]
    assert len(builder.GetSystems()) == systems and not robot.tasks


def test_a_move_may_end_at_the_latest_time_its_range_takes():
    """``t1 = 1000`` s, the top of the documented range, raised Drake's raw "Times must be in
    increasing order" (the held piece after the move started and ended there)."""
    from sotdrake.dynamics.trajectories import hold_move_hold

    trajectory = hold_move_hold(0.0, 1000.0, np.zeros(2), np.ones(2))
    assert trajectory.end_time() == 1000.0 and trajectory.value(1000.0).ravel() == pytest.approx([1.0, 1.0])
    assert trajectory.value(500.0).ravel() == pytest.approx([0.5, 0.5])
    with pytest.raises(InvalidInput, match="t1"):
        hold_move_hold(0.0, 1000.1, np.zeros(2), np.ones(2))
