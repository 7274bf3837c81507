"""The dynamic SoT: dynamics terms against Drake, τ reproducing q̈, contacts, strictness, bad
inputs, the release ramp, and short runs on RobotDynSimu and on the physics plant."""

import numpy as np
import pytest
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce, MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable, MultibodyForces, RevoluteJoint, SpatialInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake import TALOS_GRIPPERS
from sotdrake.configuration import Layout, integrate
from sotdrake.dynamics.contact import Contact6d, friction_ratio, wrench_constraints
from sotdrake.dynamics.device import integrate_acceleration
from sotdrake.dynamics.dyn_types import ContactNotFound
from sotdrake.dynamics.formulation import ActiveContact, actuated_rows, dynamic_levels, variable_bounds
from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynPosture
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.dynamics.task_dyn_pd import pd_reference
from sotdrake.dynamics.terms import acceleration_bounds, com_terms, gravity_columns
from sotdrake.exceptions import InvalidInput, StackError
from sotdrake.hqp.equality_hierarchy import solve_equality_hierarchy
from sotdrake.hqp.solve import HierarchicalQP
from sotdrake.robots import load_talos
from sotdrake.task import TaskLevel
from tests.conftest import random_configuration

SOLES = (("contactLF", "left_sole_link"), ("contactRF", "right_sole_link"))


@pytest.fixture(scope="module")
def standing():
    """A dynsimu diagram: both soles held, CoM and posture tasks; and a continuous plant of the same
    model (for Drake's forward dynamics)."""
    builder = DiagramBuilder()
    model = load_talos("reduced")
    robot = RobotDyn(builder, model, "dynsimu")
    lf, rf = robot.add_contact("contactLF", "left-sole"), robot.add_contact("contactRF", "right-sole")
    com, posture = MetaTaskDynCom(robot), MetaTaskDynPosture(robot)
    robot.sot.addContact(lf)
    robot.sot.addContact(rf)
    robot.sot.push(com.task.name)
    robot.sot.push(posture.task.name)
    diagram = builder.Build()
    return robot, diagram, com, posture


def _set_state(robot, diagram, x):
    context = diagram.CreateDefaultContext()
    robot.device.GetMyContextFromRoot(context).SetDiscreteState(x)
    return context


def _solution(robot, context):
    return robot.sot._solution.Eval(robot.sot.GetMyContextFromRoot(context))


def _random_state(model, rng, spread=0.3):
    return np.concatenate([random_configuration(model, rng, spread), rng.normal(scale=0.5, size=model.nv)])


# --- dynamics terms --------------------------------------------------------------------------
def test_terms_match_inverse_dynamics(standing, rng):
    robot, diagram, *_ = standing
    plant = robot.model.plant
    plant_context = plant.CreateDefaultContext()
    for _ in range(5):
        x = _random_state(robot.model, rng)
        context = _set_state(robot, diagram, x)
        terms = robot.dynamic.GetOutputPort("dynamics").Eval(robot.dynamic.GetMyContextFromRoot(context))
        plant.SetPositionsAndVelocities(plant_context, x)
        a = rng.normal(size=plant.num_velocities())
        forces = MultibodyForces(plant)
        plant.CalcForceElementsContribution(plant_context, forces)  # gravity is a force element
        tau_id = plant.CalcInverseDynamics(plant_context, a, forces)
        np.testing.assert_allclose(terms.M @ a + terms.h, tau_id, atol=1e-9 * max(1.0, np.abs(tau_id).max()))
        np.testing.assert_allclose(terms.M, terms.M.T, atol=1e-12)


def test_com_terms_from_base_rows_equal_drakes(standing, rng):
    robot, diagram, *_ = standing
    plant, dynamic = robot.model.plant, robot.dynamic
    plant_context = plant.CreateDefaultContext()
    world = plant.world_frame()
    for _ in range(5):
        x = _random_state(robot.model, rng)
        context = dynamic.GetMyContextFromRoot(_set_state(robot, diagram, x))
        plant.SetPositionsAndVelocities(plant_context, x)
        J = plant.CalcJacobianCenterOfMassTranslationalVelocity(plant_context, JacobianWrtVariable.kV, world, world)
        drift = plant.CalcBiasCenterOfMassTranslationalAcceleration(plant_context, JacobianWrtVariable.kV, world, world)
        np.testing.assert_allclose(dynamic.GetOutputPort("Jcom").Eval(context), J, atol=1e-12)
        np.testing.assert_allclose(dynamic.GetOutputPort("com_drift").Eval(context), drift, atol=1e-10)


def test_op_point_drift_is_the_jacobians_rate(standing, rng):
    """``J̇ v`` against a central difference of ``J`` along the motion (on SE(3) × joints)."""
    robot, diagram, *_ = standing
    plant, layout = robot.model.plant, Layout.of(robot.model.plant)
    frame = plant.GetFrameByName("right_sole_link")
    x = _random_state(robot.model, rng)
    q, v = x[:39], x[39:]
    context = robot.dynamic.GetMyContextFromRoot(_set_state(robot, diagram, x))
    drift = robot.dynamic.GetOutputPort("contactRF_drift").Eval(context)
    pc = plant.CreateDefaultContext()

    def jacobian(qq):
        plant.SetPositions(pc, qq)
        return plant.CalcJacobianSpatialVelocity(pc, JacobianWrtVariable.kV, frame, np.zeros(3), plant.world_frame(), plant.world_frame())

    h = 1e-6
    # The base velocity is (ω, v) in the world; the device's integration takes exactly that twist.
    J_dot = (jacobian(integrate(q, v, h, layout)) - jacobian(integrate(q, v, -h, layout))) / (2 * h)
    np.testing.assert_allclose(drift, J_dot @ v, atol=1e-5 * max(1.0, np.abs(drift).max()))


def test_gravity_from_the_mass_matrix_columns(standing, rng):
    """``τ_g = M[:, t] g`` against Drake's generalized gravity forces at random configurations; a
    plant for which it does not hold (gravity off for TALOS' instance) gets None."""
    robot = standing[0]
    plant = robot.model.plant
    columns, g = gravity_columns(plant, Layout.of(plant))
    pc = plant.CreateDefaultContext()
    for _ in range(5):
        plant.SetPositions(pc, random_configuration(robot.model, rng, 0.5))
        tau_g = plant.CalcGravityGeneralizedForces(pc)
        np.testing.assert_allclose(plant.CalcMassMatrix(pc)[:, columns] @ g, tau_g, rtol=0, atol=1e-10 * np.abs(tau_g).max())
    # A floating body carrying an arm whose model instance has gravity off: τ_g is not M_tᵀ g.
    plant = MultibodyPlant(0.0)
    inertia = SpatialInertia.SolidBoxWithMass(1.0, 0.1, 0.2, 0.3)
    base = plant.AddRigidBody("base", plant.AddModelInstance("robot"), inertia)
    arm_instance = plant.AddModelInstance("weightless_arm")
    arm = plant.AddRigidBody("arm", arm_instance, inertia)
    plant.AddJoint(RevoluteJoint("shoulder", base.body_frame(), arm.body_frame(), [0.0, 1.0, 0.0]))
    plant.mutable_gravity_field().set_enabled(arm_instance, False)
    plant.Finalize()
    assert gravity_columns(plant, Layout.of(plant)) is None


def test_op_point_kinematics_is_its_pose_jacobian_and_drift(standing, rng):
    """``<name>_kinematics`` (what a contact reads) holds exactly the op point's other outputs, and ``J v``."""
    robot, diagram, *_ = standing
    x = _random_state(robot.model, rng)
    dynamic = robot.dynamic
    context = dynamic.GetMyContextFromRoot(_set_state(robot, diagram, x))
    motion = dynamic.kinematics_port("contactRF").Eval(context)
    assert motion.pose.IsExactlyEqualTo(dynamic.GetOutputPort("contactRF").Eval(context))
    np.testing.assert_array_equal(motion.jacobian, dynamic.GetOutputPort("JcontactRF").Eval(context))
    np.testing.assert_array_equal(motion.drift, dynamic.drift_port("contactRF").Eval(context))
    np.testing.assert_allclose(motion.velocity, motion.jacobian @ x[robot.model.nq :], rtol=1e-14, atol=1e-14)


def test_com_terms_need_a_floating_base():
    with pytest.raises(ValueError):
        com_terms(np.eye(3), np.zeros(3), 1.0, Layout(None, None, np.arange(3), np.arange(3)))


# --- the solver ------------------------------------------------------------------------------
def test_torque_reproduces_acceleration_through_forward_dynamics(standing, rng):
    """Drake's forward dynamics of a continuous plant, driven by the solver's τ on its actuation
    input and the contact wrenches as external forces, gives the solver's q̈."""
    robot, diagram, *_ = standing
    model = load_talos("reduced")  # its own plant: the actuation input is free
    plant = model.plant
    for _ in range(3):
        x = _random_state(model, rng, spread=0.1)
        solution = _solution(robot, _set_state(robot, diagram, x))
        context = plant.CreateDefaultContext()
        plant.SetPositionsAndVelocities(context, x)
        plant.get_actuation_input_port().FixValue(context, solution.torque)
        forces = []
        for name, frame_name in SOLES:
            frame = plant.GetFrameByName(frame_name)
            force = ExternallyAppliedSpatialForce()
            force.body_index = frame.body().index()
            force.p_BoBq_B = frame.GetFixedPoseInBodyFrame().translation()
            W = solution.wrenches[name]
            force.F_Bq_W = SpatialForce(W[:3], W[3:])
            forces.append(force)
        plant.get_applied_spatial_force_input_port().FixValue(context, forces)
        v_dot = plant.EvalTimeDerivatives(context).get_vector().CopyToVector()[model.nq :]
        np.testing.assert_allclose(v_dot, solution.acceleration, atol=1e-6 * max(1.0, np.abs(v_dot).max()))


def test_contact_constraints_and_bounds_hold(standing, rng):
    robot, diagram, *_ = standing
    sot = robot.sot
    for _ in range(2):
        x = _random_state(robot.model, rng, spread=0.2)
        context = _set_state(robot, diagram, x)
        solution = _solution(robot, context)
        slack = solution.diagnostics.slack_norms
        assert slack[0] < 1e-8 and slack[1] < 1e-6  # dynamics, contacts
        assert np.all(np.abs(solution.torque) <= sot.effort * (1 + 1e-9))
        for name in ("contactLF", "contactRF"):
            contact = robot.contacts[name]
            rows = contact.GetOutputPort("contact").Eval(contact.GetMyContextFromRoot(context))
            w = solution.local_wrenches[name]
            assert np.all(rows.wrench_rows @ w <= 1e-6 * np.abs(w).max())
            assert w[5] >= rows.f_min - 1e-9
            np.testing.assert_allclose(rows.jacobian @ solution.acceleration, rows.acceleration, atol=1e-6)
            assert friction_ratio(solution.wrenches[name][3:], rows.rotation[:, 2], rows.mu) <= 1 + 1e-6


def test_torque_elimination_gives_the_full_hierarchys_optimum(standing, rng):
    """The fast path (τ eliminated, 50 unknowns) returns the optimum of the full hierarchy over
    (q̈, w, τ) when its τ is within the limits and the wrench rows hold."""
    robot, diagram, com, _ = standing
    sot, nv = robot.sot, robot.model.nv
    for _ in range(3):  # the CoM asked to move (≤ 0.5 m/s²): unequal loads, the CoPs inside the soles
        context = _set_state(robot, diagram, np.concatenate([robot.q0, np.zeros(nv)]))
        com.featureDes.setReference(com.initial_com() + np.append(rng.uniform(-0.005, 0.005, 2), 0.0), context)
        solution = _solution(robot, context)
        assert solution.diagnostics.torques_eliminated
        assert set(solution.diagnostics.level_solvers) == {"qr"}  # the equality hierarchy's QR path
        sot_context = sot.GetMyContextFromRoot(context)
        terms = sot.dynamics.Eval(sot_context)
        contacts = [ActiveContact(name, sot._contact_ports[name].Eval(sot_context)) for name, _ in SOLES]
        tasks = sot._tasks(sot_context, sot._settings_of(sot_context))
        levels, slices = dynamic_levels(terms, contacts, tasks, 10.0, loads=None)
        a_lo, a_up = acceleration_bounds(terms.q, terms.v, *sot._limits, 0.05, 1e-3, sot.layout, dt=sot.dt)
        lower, upper = variable_bounds(nv, contacts, slices, a_lo, a_up, sot.effort)
        full = HierarchicalQP(len(lower)).solve(levels, lower, upper).x
        np.testing.assert_allclose(solution.acceleration, full[:nv], atol=1e-6)
        np.testing.assert_allclose(solution.torque, full[-sot.na:], atol=1e-5 * np.abs(full[-sot.na:]).max())
        np.testing.assert_allclose(solution.local_wrenches["contactLF"], full[slices[0]], atol=1e-4)


def test_qr_path_is_the_hqps_answer_on_talos(standing, rng):
    """On TALOS' dynamic levels (both soles, CoM, posture, damping; τ eliminated; the grippers
    fixed by the control selection), the QR path gives the hierarchical QP's point."""
    robot, diagram, com, _ = standing
    sot, nv = robot.sot, robot.model.nv
    for spread in (0.0, 0.05):
        x = _random_state(robot.model, rng, spread) if spread else np.concatenate([robot.q0, np.zeros(nv)])
        context = _set_state(robot, diagram, x)
        sot_context = sot.GetMyContextFromRoot(context)
        terms = sot.dynamics.Eval(sot_context)
        contacts = [ActiveContact(name, sot._contact_ports[name].Eval(sot_context)) for name, _ in SOLES]
        tasks = sot._tasks(sot_context, sot._settings_of(sot_context))
        actuated = actuated_rows(terms.B)
        levels, slices = dynamic_levels(terms, contacts, tasks, 10.0, False, np.array([400.0, 300.0]), actuated)
        a_lo, a_up = acceleration_bounds(terms.q, terms.v, *sot._limits, 0.05, 1e-3, sot.layout, dt=sot.dt)
        a_lo[:6] = a_up[:6] = 0.0  # some fixed components too
        lower, upper = variable_bounds(nv, contacts, slices, a_lo, a_up, sot.effort)
        m = len(lower) - sot.na
        qr = solve_equality_hierarchy([(level.A, level.b_eq) for level in levels], lower[:m], upper[:m])
        reference = HierarchicalQP(m).solve(levels, lower[:m], upper[:m])
        if not spread:
            # Standing: every rank decision clear by orders of magnitude (the smallest singular value
            # kept 9e-3 against CERTIFIED 1e-5, the round-off ones 1e-16 against NEGLIGIBLE 1e-11),
            # and no bound passed by more than round-off (1e-16 against IN_THE_WAY 1e-9): on any CPU.
            assert qr is not None
        assert qr is not None or not np.all((reference.x >= lower[:m]) & (reference.x <= upper[:m]))
        if qr is not None:
            scale = np.abs(reference.x).max()
            np.testing.assert_allclose(qr.x, reference.x, rtol=0, atol=1e-9 * scale)
            np.testing.assert_allclose(qr.slack_norms, reference.slack_norms, rtol=1e-6, atol=1e-9 * scale)


def test_levels_and_bounds_match_their_definitions(standing, rng):
    """The levels and bounds the solver assembles (cached structure, views, batched products)
    against a direct construction from the module docstring: ``[M, −J_cᵀ diag(R, R), −B] x = −h``,
    the contacts' ``[J_c 0]``, each task's ``[J 0]``, ``[I 0]`` and the weighted regularization rows;
    the bounds from :func:`acceleration_bounds` and :func:`variable_bounds` with the control
    selection applied (exactly equal)."""
    from sotdrake.dynamics.contact import world_wrench_map
    from sotdrake.dynamics.formulation import shear_weights, wrench_regularization

    robot, diagram, *_ = standing
    sot, nv, na = robot.sot, robot.model.nv, robot.sot.na
    context = _set_state(robot, diagram, _random_state(robot.model, rng, 0.05))
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS), context)  # the grippers held
    sot_context = sot.GetMyContextFromRoot(context)
    s = sot._settings_of(sot_context)
    terms = sot.dynamics.Eval(sot_context)
    contacts = [ActiveContact(name, sot._contact_ports[name].Eval(sot_context)) for name, _ in SOLES]
    tasks = sot._tasks(sot_context, s)
    loads = np.array([400.0, 35.0])
    for actuated in (None, actuated_rows(terms.B)):
        levels, slices = dynamic_levels(terms, contacts, tasks, 10.0, False, loads, actuated)
        n = nv + 12 + (na if actuated is None else 0)
        maps = [world_wrench_map(c.rows.rotation) for c in contacts]
        dynamics = np.hstack([terms.M] + [-c.rows.jacobian.T @ W for c, W in zip(contacts, maps, strict=True)] + [-terms.B])
        h = terms.h
        if actuated is not None:
            passive = np.setdiff1d(np.arange(nv), actuated)
            dynamics, h = dynamics[passive, :n], h[passive]
        np.testing.assert_allclose(levels[0].A, dynamics, rtol=0, atol=1e-12 * np.abs(dynamics).max())
        np.testing.assert_array_equal(levels[0].b_eq, -h)
        np.testing.assert_array_equal(levels[1].A, np.hstack([np.vstack([c.rows.jacobian for c in contacts]), np.zeros((12, n - nv))]))
        for level, task in zip(levels[2:-1], tasks, strict=True):
            np.testing.assert_array_equal(level.A, np.hstack([task.jacobian, np.zeros((len(task.jacobian), n - nv))]))
        damping = np.zeros((nv + 10, n))
        damping[:nv, :nv] = np.eye(nv)
        for i, (c, weight) in enumerate(zip(contacts, shear_weights(loads, 2), strict=True)):
            damping[nv + 5 * i : nv + 5 * i + 5, nv + 6 * i : nv + 6 * i + 6] = wrench_regularization(c, 6, float(weight))
        np.testing.assert_allclose(levels[-1].A, damping, rtol=1e-15, atol=0)
        np.testing.assert_array_equal(levels[-1].b_eq, np.concatenate([-10.0 * terms.v, np.zeros(10)]))
    a_lo, a_up = acceleration_bounds(terms.q, terms.v, *sot._limits, s.horizon, s.position_margin, sot.layout, dt=sot.dt)
    a_lo[~s.control_selection] = a_up[~s.control_selection] = 0.0
    expected = variable_bounds(nv, contacts, slices, a_lo, a_up, sot.effort)
    for got, want in zip(sot._bounds(terms, s, contacts, slices), expected, strict=True):
        np.testing.assert_array_equal(got, want)


def test_friction_and_cop_rows():
    A = wrench_constraints(0.5, (-0.1, 0.1, -0.05, 0.05), 0.0)
    inside = np.array([1.0, -2.0, 0.0, 10.0, 10.0, 100.0])  # CoP (0.02, 0.01), ‖f_t‖ = 14 N ≤ 50 N
    assert np.all(A @ inside <= 0)
    for bad in ([0, -11.0, 0, 0, 0, 100], [6.0, 0, 0, 0, 0, 100], [0, 0, 0, 36.0, 0, 100]):
        assert np.any(A @ np.array(bad) > 0)  # CoP at x = 0.11, y = 0.06; f_x > μ/√2 f_z
    assert wrench_constraints(0.5, None, 0.0).shape == (4, 3)  # a point contact: friction only


def test_strict_hierarchy_on_random_dynamic_stacks(standing, rng):
    """A lower task never changes a higher level's optimal slack (strictness), on random
    conflicting acceleration tasks under the dynamics and both contacts."""
    robot, diagram, *_ = standing
    sot = robot.sot
    nv = robot.model.nv
    for _trial in range(2):
        x = _random_state(robot.model, rng, spread=0.1)
        context = _set_state(robot, diagram, x)
        terms = robot.dynamic.GetOutputPort("dynamics").Eval(robot.dynamic.GetMyContextFromRoot(context))
        contacts = [ActiveContact(name, robot.contacts[name].GetOutputPort("contact").Eval(
            robot.contacts[name].GetMyContextFromRoot(context))) for name in ("contactLF", "contactRF")]
        tasks = []
        for size in rng.integers(3, 12, size=3):
            J = rng.normal(size=(size, nv))
            b = rng.normal(scale=5.0, size=size)
            tasks.append(TaskLevel(J, b, b, b))
        a_lo, a_up = acceleration_bounds(terms.q, terms.v, *sot._limits, 0.05, 1e-3, sot.layout, dt=sot.dt)
        hqp = HierarchicalQP(nv + 12 + sot.na)
        slacks = []
        for k in range(1, 4):
            levels, slices = dynamic_levels(terms, contacts, tasks[:k], 10.0)
            lower, upper = variable_bounds(nv, contacts, slices, a_lo, a_up, sot.effort)
            slacks.append(hqp.solve(levels, lower, upper).slack_norms)
        for k in range(1, 3):  # the levels common to both stacks keep their slack
            common = 2 + k  # dynamics, contacts, tasks[:k]
            np.testing.assert_allclose(slacks[k][:common], slacks[k - 1][:common], atol=1e-6, rtol=1e-6)
        assert slacks[-1][0] < 1e-8 and slacks[-1][1] < 1e-6


def test_shear_follows_the_load(standing):
    """The wrench regularization shares the shear in proportion to the normal forces (each sole
    uses the same fraction of its friction cone). With the regularization unweighted (no loads) the
    shear was shared equally, and the nearly unloaded sole of the sway reached its friction bound
    (then slipped on the physics plant): here the light sole's ratio was 5× the loaded one's."""
    robot, diagram, *_ = standing
    sot, nv = robot.sot, robot.model.nv
    context = _set_state(robot, diagram, np.concatenate([robot.q0, np.zeros(nv)]))
    terms = robot.dynamic.GetOutputPort("dynamics").Eval(robot.dynamic.GetMyContextFromRoot(context))
    contacts = [ActiveContact(name, robot.contacts[name].GetOutputPort("contact").Eval(
        robot.contacts[name].GetMyContextFromRoot(context))) for name, _ in SOLES]
    Jcom = robot.dynamic.GetOutputPort("Jcom").Eval(robot.dynamic.GetMyContextFromRoot(context))
    com = TaskLevel(Jcom, np.array([0.3, -0.5, 0.0]), np.array([0.3, -0.5, 0.0]), np.zeros(3))  # ZMP ~4.5 cm left
    a_lo, a_up = acceleration_bounds(terms.q, terms.v, *sot._limits, 0.05, 1e-3, sot.layout, dt=sot.dt)
    hqp = HierarchicalQP(nv + 12 + sot.na)

    def ratios(loads):
        levels, slices = dynamic_levels(terms, contacts, [com], 10.0, loads=loads)
        lower, upper = variable_bounds(nv, contacts, slices, a_lo, a_up, sot.effort)
        x = hqp.solve(levels, lower, upper).x
        w = [x[sl] for sl in slices]
        return np.array([np.hypot(*wc[3:5]) / wc[5] for wc in w]), np.array([wc[5] for wc in w])

    equal, loads = ratios(None)
    assert loads[0] > 4 * loads[1]  # the left sole carries most of the weight
    assert equal[1] > 4 * equal[0]  # equal shares: the light sole near its bound
    for _ in range(2):  # the loads of the previous tick, as SolverDyn does
        weighted, loads = ratios(loads)
    np.testing.assert_allclose(weighted[1], weighted[0], rtol=0.01)
    assert weighted.max() < 0.5 * equal.max()


def test_solver_records_the_previous_loads(standing):
    """The shear weights of a tick come from the normal forces of the tick before (discrete state)."""
    robot, diagram, *_ = standing
    simulator = Simulator(diagram)
    context = simulator.get_context()
    sot_context = robot.sot.GetMyContextFromRoot(context)
    assert robot.sot.previous_loads(sot_context, ["contactLF", "contactRF"]) is None  # nothing recorded yet
    simulator.AdvanceTo(0.002)
    before = _solution(robot, context).local_wrenches
    simulator.AdvanceTo(0.003)  # the update of t = 0.002 s records that tick's solution
    loads = robot.sot.previous_loads(sot_context, ["contactLF", "contactRF"])
    np.testing.assert_array_equal(loads, [before["contactLF"][5], before["contactRF"][5]])


def test_a_bound_in_the_way_is_held_by_the_qr_path(standing, monkeypatch):
    """A tick whose optimum has a bound active (the right sole's normal force held at a raised
    f_min) is answered by the QR path holding that bound at equality, certified by its multiplier:
    the hierarchical QP's point. The bound is remembered (discrete state), so the next ticks start
    from it: one sweep each. Once f_min is lowered the remembered bound is released (its multiplier
    turns negative) and the point is the unbounded one."""
    import sotdrake.hqp.equality_hierarchy as equality_hierarchy

    robot, diagram, *_ = standing
    sot, nv = robot.sot, robot.model.nv
    sweeps: list[dict] = []
    sweep = equality_hierarchy._sweep
    monkeypatch.setattr(equality_hierarchy, "_sweep", lambda *a: sweeps.append(dict(a[3])) or sweep(*a))
    simulator = Simulator(diagram)
    context = simulator.get_context()
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS), context)  # as the scripts
    right = robot.contacts["contactRF"]
    right.setMinimumNormalForce(600.0, context)  # more than its share of TALOS' weight
    solution = _solution(robot, context)  # the tick at t = 0
    assert set(solution.diagnostics.level_solvers) == {"qr"} and solution.diagnostics.torques_eliminated
    assert solution.local_wrenches["contactRF"][5] == pytest.approx(600.0, abs=1e-9)
    assert len(sweeps) == 2 and not sweeps[0]  # unbounded, then with the normal force held
    normal = nv + 11  # f_z of the right sole in (q̈, w_LF, w_RF)
    assert list(solution.diagnostics.active_bounds) == [normal]

    sot_context = sot.GetMyContextFromRoot(context)
    terms = sot.dynamics.Eval(sot_context)
    contacts = sot._active_contacts(sot_context, sot._settings_of(sot_context))
    tasks = sot._tasks(sot_context, sot._settings_of(sot_context))
    levels, slices = dynamic_levels(terms, contacts, tasks, 10.0, False, None, actuated_rows(terms.B))
    a_lo, a_up = acceleration_bounds(terms.q, terms.v, *sot._limits, 0.05, 1e-3, sot.layout, dt=sot.dt)
    a_lo[~sot._settings_of(sot_context).control_selection] = a_up[~sot._settings_of(sot_context).control_selection] = 0.0
    lower, upper = variable_bounds(nv, contacts, slices, a_lo, a_up, sot.effort)
    m = len(lower) - sot.na
    reference = HierarchicalQP(m).solve(levels, lower[:m], upper[:m], start=np.clip(0.0, lower[:m], upper[:m]))
    assert list(reference.active_bounds) == [normal]
    scale = np.abs(reference.x).max()
    np.testing.assert_allclose(solution.acceleration, reference.x[:nv], rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(solution.local_wrenches["contactRF"], reference.x[slices[1]], rtol=0, atol=1e-9 * scale)

    simulator.AdvanceTo(0.0005)  # the update at t = 0 remembers the bound
    assert sot.held_bound_guess(sot_context)[0] == normal + 1  # at its lower bound
    del sweeps[:]
    simulator.AdvanceTo(0.0035)  # three more ticks, each from the remembered bound: one sweep
    assert sweeps == [{normal: 1.0}] * 3
    right.setMinimumNormalForce(1.0, context)
    del sweeps[:]
    solution = _solution(robot, context)
    assert sweeps == [{normal: 1.0}, {}]  # the remembered bound released, then the unbounded sweep
    assert solution.diagnostics.active_bounds.size == 0 and solution.local_wrenches["contactRF"][5] > 1.0


def test_stiff_com_after_a_push_spends_the_torques(standing):
    """After the long push the CoM moves at 0.11 m/s (feet still). The CoP bounds allow about
    1 m/s² of CoM deceleration; a CoM task with K_v = 20 asks 2.2 m/s², and the hierarchy meets it
    by whirling the upper body (angular momentum): the torques reach their limits and the posture
    below is abandoned, which on the physics plant made the soles slip 2 cm. With K_p = 20 (the
    push scenario's) the same state asks what the soles can give."""
    robot, diagram, com, _ = standing
    dynamic = robot.dynamic
    context = _set_state(robot, diagram, np.concatenate([robot.q0, np.zeros(robot.model.nv)]))
    own = dynamic.GetMyContextFromRoot(context)
    A = np.vstack([dynamic.GetOutputPort("J" + name).Eval(own) for name, _ in SOLES] + [dynamic.GetOutputPort("Jcom").Eval(own)])
    v = np.linalg.lstsq(A, np.concatenate([np.zeros(12), [0.11, 0.0, 0.0]]), rcond=None)[0]
    outcome = {}
    for kp in (100.0, 20.0):
        context = _set_state(robot, diagram, np.concatenate([robot.q0, v]))
        com.task.setGain(kp, context=context)
        solution = _solution(robot, context)
        assert solution.residuals[2] < 1e-8  # the CoM level is met in both cases...
        outcome[kp] = (np.abs(solution.torque / robot.sot.effort).max(), solution.residuals[3])
    assert outcome[100.0][0] > 0.999 and outcome[20.0][0] < 0.95  # ...at the torque limits with the stiff gain
    assert outcome[100.0][1] > 5 * outcome[20.0][1]  # and the posture is abandoned


def test_acceleration_bounds_stop_a_joint_at_its_limit(talos_model):
    layout = Layout.of(talos_model.plant)
    limits = talos_model.joint_limits()
    q, v = talos_model.half_sitting.copy(), np.zeros(talos_model.nv)
    joint = talos_model.plant.GetJointByName("leg_left_4_joint")
    iq, iv = joint.position_start(), joint.velocity_start()
    q[iq] = limits["position_upper"][iq] - 0.01
    v[iv] = 1.0
    lower, upper = acceleration_bounds(q, v, limits["position_lower"], limits["position_upper"],
                                       limits["velocity_lower"], limits["velocity_upper"], 0.05, 1e-3, layout, dt=1e-3)
    assert np.all(lower <= upper) and np.isinf(upper[:6]).all()
    T = 0.05  # q + v T + ½ a T² stays below the limit with the largest allowed a
    assert q[iq] + v[iv] * T + 0.5 * upper[iv] * T**2 <= limits["position_upper"][iq] - 1e-3 + 1e-12


# --- bad inputs --------------------------------------------------------------------------------
def test_bad_inputs_raise_and_change_nothing(standing):
    robot, diagram, com, _ = standing
    sot, lf = robot.sot, robot.contacts["contactLF"]
    context = diagram.CreateDefaultContext()
    for mu in (0.0, -0.5, np.nan):
        with pytest.raises(InvalidInput, match="μ"):
            lf.setFriction(mu, context)
    assert lf.settings(context).mu == 0.7
    with pytest.raises(InvalidInput):
        Contact6d("bad", robot.model.nv, (-0.1, 0.1, -0.05, 0.05), mu=0.0)
    with pytest.raises(ContactNotFound, match="contactLF"):
        sot.rmContact("contactXX", context=context)
    with pytest.raises(ContactNotFound):
        sot.addContact("contactXX", context=context)
    sot.rmContact("contactRF", 0.2, context=context)
    with pytest.raises(StackError, match="last contact"):
        sot.rmContact("contactLF", context=context)
    assert sot.settings(context).contacts == ["contactLF", "contactRF"]
    assert sot.settings(context).releasing == {"contactRF": 0.2}
    with pytest.raises(InvalidInput):
        sot.rmContact("contactLF", -1.0, context=context)
    for kp, kv in ((-1.0, 1.0), (1.0, -1.0), (np.inf, 1.0)):
        with pytest.raises(InvalidInput, match="K"):
            com.task.setGain(kp, kv, context)
    assert (com.task.settings(context).kp, com.task.settings(context).kv) == (100.0, 20.0)
    with pytest.raises(InvalidInput):
        sot.setDampingGain(-1.0, context)
    with pytest.raises(InvalidInput):
        lf.setMinimumNormalForce(-1.0, context)


def test_pd_reference_formula():
    e, e_dot, drift, ref = np.array([0.1, -0.2]), np.array([1.0, 0.5]), np.array([0.3, 0.0]), np.array([2.0, 1.0])
    np.testing.assert_allclose(pd_reference(e, e_dot, 100.0, 20.0, ref, drift), -100 * e - 20 * e_dot + ref - drift)


def test_task_dyn_pd_reads_a_feature_or_its_three_signals():
    """The ``feature`` port (one FeatureValue) and the ``error``/``jacobian``/``errordot`` ports
    give the same rows ``J q̈ = −K_p e − K_v (J v + ė_ref)`` (first tick: no J̇)."""
    from sotdrake.dynamics.task_dyn_pd import TaskDynPD
    from sotdrake.features import FeatureValue

    rng = np.random.default_rng(3)
    nv = 5
    e, J, e_ref, v = rng.normal(size=2), rng.normal(size=(2, nv)), rng.normal(size=2), rng.normal(size=nv)
    rows = []
    for through_feature in (True, False):
        task = TaskDynPD("task", nv, 1e-3, kp=9.0, kv=4.0)
        context = task.CreateDefaultContext()
        if through_feature:
            task.GetInputPort("feature").FixValue(context, FeatureValue(e, J, e_ref))
        else:
            task.GetInputPort("error").FixValue(context, e)
            task.GetInputPort("jacobian").FixValue(context, J)
            task.GetInputPort("errordot").FixValue(context, e_ref)
        task.GetInputPort("velocity").FixValue(context, v)
        rows.append(task.GetOutputPort("task").Eval(context))
    for level in rows:
        np.testing.assert_array_equal(level.jacobian, J)
        np.testing.assert_allclose(level.lower, -9.0 * e - 4.0 * (J @ v + e_ref), rtol=1e-14)


def test_task_dyn_pd_with_an_exact_drift_keeps_no_memory():
    """``exact_drift=True`` (the CoM's wiring): the same rows as with the drift read when connected,
    no discrete state and no per-tick update; without a dimension (no drift input) it is refused."""
    from sotdrake.dynamics.task_dyn_pd import TaskDynPD
    from sotdrake.features import FeatureValue

    rng = np.random.default_rng(4)
    nv = 5
    e, J, e_ref, v, drift = rng.normal(size=2), rng.normal(size=(2, nv)), rng.normal(size=2), rng.normal(size=nv), rng.normal(size=2)
    rows = []
    for exact in (False, True):
        task = TaskDynPD("task", nv, 1e-3, kp=9.0, kv=4.0, dimension=2, exact_drift=exact)
        context = task.CreateDefaultContext()
        assert context.num_discrete_state_groups() == (0 if exact else 1)
        task.GetInputPort("feature").FixValue(context, FeatureValue(e, J, e_ref))
        task.GetInputPort("velocity").FixValue(context, v)
        task.GetInputPort("drift").FixValue(context, drift)
        rows.append(task.GetOutputPort("task").Eval(context).lower)
    np.testing.assert_array_equal(rows[0], rows[1])
    np.testing.assert_allclose(rows[1], -9.0 * e - 4.0 * (J @ v + e_ref) - drift, rtol=1e-14)
    with pytest.raises(InvalidInput, match="exact_drift"):
        TaskDynPD("task", nv, 1e-3, exact_drift=True)


def test_robot_dyn_simu_integrates_exactly(talos_model):
    layout = Layout.of(talos_model.plant)
    q, v = talos_model.half_sitting.copy(), np.zeros(talos_model.nv)
    a = np.zeros(talos_model.nv)
    a[layout.joints_v] = 0.5
    dt, n = 1e-3, 100
    for _ in range(n):
        q, v = integrate_acceleration(q, v, a, dt, layout)
    # semi-implicit Euler: q_n = q_0 + a dt² n (n + 1)/2
    np.testing.assert_allclose(q[layout.joints_q] - talos_model.half_sitting[layout.joints_q], 0.5 * dt**2 * n * (n + 1) / 2)
    np.testing.assert_allclose(v[layout.joints_v], 0.5 * n * dt)


# --- runs ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def dynamics_script():
    from sotdrake.scenarios import talos_dynamics

    return talos_dynamics


def test_release_ramps_the_force_to_zero_then_frees_the_foot(standing):
    robot, diagram, *_ = standing
    simulator = Simulator(diagram)
    context = simulator.get_context()
    sot = robot.sot
    simulator.AdvanceTo(0.01)
    sot.rmContact("contactRF", 0.03, context=context)
    forces = []
    for k in range(1, 5):
        simulator.AdvanceTo(0.01 + 0.01 * k)
        forces.append(_solution(robot, context).local_wrenches.get("contactRF", np.zeros(6))[5])
    # The ramp starts at the first tick after the command (Drake runs the update of t = 0.01 s when
    # leaving 0.01 s: t0 = 0.01 s) from the force then; with the CoM held between the feet the
    # bound is active, so the force follows the line exactly.
    f0 = forces[0] / (1 - (0.02 - 0.01) / 0.03)
    assert f0 > 300.0  # it carried about half the weight when released
    for k, force in enumerate(forces[:2]):
        assert force == pytest.approx(f0 * (1 - (0.01 * k + 0.01) / 0.03), rel=1e-6)
    assert sot.held_contacts(context) == ["contactLF"] and forces[-1] == 0.0


def test_release_ramps_both_bounds_of_the_normal_force(standing):
    """While a contact is released its normal force lies between f_min·(1 − s) and f0·(1 − s)
    (s the ramp's progress): no jump from f_min to 0 at the release."""
    robot, diagram, *_ = standing
    context = _set_state(robot, diagram, np.concatenate([robot.q0, np.zeros(robot.model.nv)]))
    contact = robot.contacts["contactRF"]
    rows = contact.GetOutputPort("contact").Eval(contact.GetMyContextFromRoot(context))._replace(f_min=30.0)
    nv = robot.model.nv
    releasing = ActiveContact("contactRF", rows, f_max=0.4 * 200.0, f_low=0.4 * 30.0)
    lower, upper = variable_bounds(nv, [releasing], [slice(nv, nv + 6)], np.zeros(nv), np.zeros(nv), robot.sot.effort)
    assert (lower[nv + 5], upper[nv + 5]) == (12.0, 80.0)
    nearly_free = ActiveContact("contactRF", rows, f_max=5.0, f_low=12.0)  # a force released below f_min
    lower, upper = variable_bounds(nv, [nearly_free], [slice(nv, nv + 6)], np.zeros(nv), np.zeros(nv), robot.sot.effort)
    assert (lower[nv + 5], upper[nv + 5]) == (5.0, 5.0)
    held = ActiveContact("contactRF", rows)
    lower, upper = variable_bounds(nv, [held], [slice(nv, nv + 6)], np.zeros(nv), np.zeros(nv), robot.sot.effort)
    assert (lower[nv + 5], upper[nv + 5]) == (30.0, np.inf)


def test_stand_short_on_dynsimu(dynamics_script):
    """RobotDynSimu: the dynamics are the solver's own, so the robot stands exactly."""
    run = dynamics_script.build_diagram("stand", "dynsimu")
    simulator, times = dynamics_script.simulate_ticks(run, 0.2, progress=False)
    summary, _ = dynamics_script.summarize(run, simulator, times, 0.2)
    assert not summary["fell"] and summary["com_drift_m"] < 1e-9 and summary["max_foot_slip_m"] < 1e-9
    assert summary["max_torque_ratio"] <= 1.0 + 1e-9


@pytest.mark.parametrize("scenario", ["lift_leg_no_com", "squat", "push"])
def test_every_scenario_builds_and_runs(dynamics_script, scenario):
    """The scenarios the tests above do not run: built and run for 20 ms on RobotDynSimu, the
    robot standing, the torques within the limits."""
    run = dynamics_script.build_diagram(scenario, "dynsimu")
    simulator, times = dynamics_script.simulate_ticks(run, 0.02, progress=False)
    summary, _ = dynamics_script.summarize(run, simulator, times, 0.02)
    assert not summary["fell"] and summary["max_torque_ratio"] <= 1.0 + 1e-9


@pytest.mark.parametrize("contact, contact_solver", [("hydroelastic", "sap"), ("hydroelastic", "tamsi"), ("point", "tamsi")])
def test_stand_short_on_physics(dynamics_script, contact, contact_solver):
    """Torque control of the simulated TALOS for 0.25 s, with each sole model and contact solver:
    the feet carry the weight as the solver says, no slip, torques within limits, the measured
    forces inside the friction cone."""
    run = dynamics_script.build_diagram("stand", "physics", contact=contact, contact_solver=contact_solver)
    simulator, times = dynamics_script.simulate_ticks(run, 0.25, progress=False)
    summary, trace = dynamics_script.summarize(run, simulator, times, 0.25)
    assert (summary["contact"], summary["contact_solver"]) == (contact, contact_solver)
    assert not summary["fell"]
    assert summary["com_drift_m"] < 1e-3 and summary["max_foot_slip_m"] < 1e-4
    assert summary["max_torque_ratio"] <= 1.0 + 1e-9 and summary["max_friction_ratio"] < 1.0
    assert summary["max_friction_ratio_settled"] <= summary["max_friction_ratio"]
    if contact == "hydroelastic":  # (standing still once the soles have landed: far inside the cone)
        assert summary["max_friction_ratio_settled"] < 0.1
    feet = trace["feet"][-1]
    assert feet[2] + feet[5] == pytest.approx(90.27 * 9.81, rel=0.02)
    np.testing.assert_allclose(feet[[2, 5]], trace["wrenches"][-1, [5, 11]], rtol=0.05)


def test_physics_records_the_solve_the_plant_applies(dynamics_script):
    """On the simulated TALOS, the solver's per-tick record (each contact's normal force) is that of
    the solve whose torque the plant's step applied, not of a second solve at the stepped state."""
    run = dynamics_script.build_diagram("stand", "physics")
    simulator = Simulator(run.diagram)
    context = simulator.get_context()
    sot, sot_context = run.robot.sot, run.robot.sot.GetMyContextFromRoot(context)
    simulator.AdvanceTo(0.003)
    for tick in range(4, 9):
        applied = _solution(run.robot, context).local_wrenches  # what the plant's next step reads
        simulator.AdvanceTo(tick * 1e-3)
        loads = sot.previous_loads(sot_context, ["contactLF", "contactRF"])
        np.testing.assert_array_equal(loads, [applied["contactLF"][5], applied["contactRF"][5]])


def test_derated_torque_bounds_bind_and_hold(standing):
    """``effort_scale``: TALOS standing needs about 0.27 of its effort limits; with the solver's
    bounds at 20 % of them, some |τ| sits on its bound and none exceeds it."""
    robot, diagram, *_ = standing
    x0 = np.concatenate([robot.q0, np.zeros(robot.model.nv)])
    full = np.abs(_solution(robot, _set_state(robot, diagram, x0)).torque) / robot.sot.effort
    assert full.max() > 0.22
    builder = DiagramBuilder()
    derated = RobotDyn(builder, robot.model, "dynsimu", effort_scale=0.2)
    lf, rf = derated.add_contact("contactLF", "left-sole"), derated.add_contact("contactRF", "right-sole")
    com, posture = MetaTaskDynCom(derated), MetaTaskDynPosture(derated)
    for contact in (lf, rf):
        derated.sot.addContact(contact)
    derated.sot.push(com.task.name)
    derated.sot.push(posture.task.name)
    diagram_derated = builder.Build()
    np.testing.assert_allclose(derated.sot.effort, 0.2 * robot.sot.effort)
    ratio = np.abs(_solution(derated, _set_state(derated, diagram_derated, x0)).torque) / derated.sot.effort
    assert ratio.max() <= 1 + 1e-9 and ratio.max() > 1 - 1e-6


@pytest.mark.parametrize("device, options", [
    ("physics", {"contact": "mesh"}), ("physics", {"contact_solver": "SAP"}), ("physics", {"contact_solver": ["sap"]}),
    ("physics", {"contact": None}), ("dynsimu", {"contact": "point"}), ("dynsimu", {"contact_solver": "tamsi"})])
def test_a_contact_option_the_device_does_not_take_is_refused(device, options):
    builder = DiagramBuilder()
    with pytest.raises(InvalidInput, match="contact"):
        RobotDyn(builder, load_talos("reduced"), device, **options)
    assert not builder.GetSystems()  # refused before anything was added


@pytest.mark.parametrize("scale", [0.0, -0.5, 1.5, float("nan"), True, "1"])
def test_effort_scale_outside_its_range_is_refused(scale):
    with pytest.raises(InvalidInput, match="effort_scale"):
        RobotDyn(DiagramBuilder(), load_talos("reduced"), "dynsimu", effort_scale=scale)


def test_task_dyn_pd_records_its_jacobian_only_while_in_the_stack():
    """With ``stack`` connected: outside the stack the update records no Jacobian, so the first tick
    in the stack takes ``J̇ = 0``; in it, the next tick's rows carry ``(J_k − J_{k−1})/dt · v``."""
    from sotdrake.dynamics.task_dyn_pd import TaskDynPD
    from sotdrake.features import FeatureValue

    rng = np.random.default_rng(5)
    nv, dt = 5, 1e-3
    e, J0, J1, v = rng.normal(size=2), rng.normal(size=(2, nv)), rng.normal(size=(2, nv)), rng.normal(size=nv)
    task = TaskDynPD("task", nv, dt, kp=9.0, kv=4.0)
    context = task.CreateDefaultContext()
    task.GetInputPort("velocity").FixValue(context, v)

    def tick(J, stack):
        task.GetInputPort("feature").FixValue(context, FeatureValue(e, J, np.zeros(2)))
        task.GetInputPort("stack").FixValue(context, stack)
        lower = task.GetOutputPort("task").Eval(context).lower.copy()
        context.SetDiscreteState(task.EvalUniquePeriodicDiscreteUpdate(context).get_vector().value())
        return lower

    def rows(J, drift):
        return -9.0 * e - 4.0 * (J @ v) - drift

    tick(J0, ("other",))  # out of the stack: nothing recorded
    np.testing.assert_allclose(tick(J1, ("task",)), rows(J1, 0.0), rtol=1e-14)  # enters: J̇ = 0, J1 recorded
    np.testing.assert_allclose(tick(J0, ("task",)), rows(J0, (J0 - J1) @ v / dt), rtol=1e-12)
    tick(J1, ("task", "other"))
    tick(J0, ())  # leaves the stack: the memory is dropped
    np.testing.assert_allclose(tick(J1, ("task",)), rows(J1, 0.0), rtol=1e-14)


def test_a_task_waiting_to_be_pushed_computes_nothing():
    """In a RobotDyn the solver's ``stack`` reaches every TaskDynPD that keeps a previous Jacobian:
    the foot's 6D feature is not computed until its task is pushed."""
    builder = DiagramBuilder()
    robot = RobotDyn(builder, load_talos("reduced"), "dynsimu")
    for name, sole in (("contactLF", "left-sole"), ("contactRF", "right-sole")):
        robot.sot.addContact(robot.add_contact(name, sole))
    posture = MetaTaskDynPosture(robot)
    robot.sot.push(posture.task.name)
    foot = MetaTaskDyn6d("RF", robot, "right-foot", "right-sole", kp=400.0)
    calls = []
    compute = foot.feature._compute
    foot.feature._compute = lambda *args: calls.append(1) or compute(*args)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(0.005)
    assert not calls
    robot.sot.push(foot.task.name, simulator.get_mutable_context())
    simulator.AdvanceTo(0.01)
    assert len(calls) >= 5


def test_the_script_refuses_a_contact_option_off_the_physics_device(dynamics_script, capsys):
    with pytest.raises(SystemExit) as stop:
        dynamics_script.main(["--device", "dynsimu", "--contact-solver", "tamsi", "--no-meshcat", "--quiet"])
    assert stop.value.code == 2 and "device='physics'" in capsys.readouterr().err
