"""The inverse-dynamics formulation alone (``sotdrake.dynamics.formulation``): its rows are the
equations of motion, the contacts' and the tasks' rows; its bounds are the joint, force and effort
limits; its torques are Drake's inverse dynamics. No system, no solver."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable, MultibodyForces
from scipy.spatial.transform import Rotation

from sotdrake.configuration import Layout
from sotdrake.dynamics.contact import ContactRows, world_wrench, wrench_constraints
from sotdrake.dynamics.formulation import (
    ActiveContact,
    actuated_rows,
    dynamic_rows,
    inside,
    normal_force_limits,
    shear_weights,
    torques_of,
    unactuated_rows,
    variable_bounds,
    wrench_slices,
)
from sotdrake.dynamics.terms import DynamicsTerms
from sotdrake.task import TaskLevel

from .conftest import random_configuration

NV = 12
SOLE = (-0.1, 0.12, -0.05, 0.06)


def random_problem(rng: np.random.Generator, kinds: tuple[int, ...], task_rows: tuple[int, ...]):
    """Terms over a floating base (6 unactuated rows) and NV − 6 actuated joints, contacts of the
    given sizes (6: a sole, 3: a point), equality tasks of the given rows."""
    L = rng.standard_normal((NV, NV))
    B = np.zeros((NV, NV - 6))
    B[6:] = np.eye(NV - 6)
    terms = DynamicsTerms(L @ L.T + NV * np.eye(NV), 100 * rng.standard_normal(NV), rng.standard_normal(NV), B,
                          rng.standard_normal(NV + 1), rng.standard_normal(NV), 50.0)
    contacts = []
    for i, k in enumerate(kinds):
        rotation = Rotation.random(random_state=rng.integers(1 << 30)).as_matrix()
        centre = (0.0, 0.0) if k == 3 else ((SOLE[0] + SOLE[1]) / 2, (SOLE[2] + SOLE[3]) / 2)
        rows = ContactRows(rng.standard_normal((k, NV)), rng.standard_normal(k), rotation,
                           wrench_constraints(0.7, SOLE if k == 6 else None, 0.01), 30.0, 0.7, centre)
        contacts.append(ActiveContact(f"contact{i}", rows))
    tasks = []
    for m in task_rows:
        rhs = rng.standard_normal(m)
        tasks.append(TaskLevel(rng.standard_normal((m, NV)), rhs, rhs, rhs))
    return terms, contacts, tasks


def split(x: np.ndarray, contacts: list[ActiveContact], slices: list[slice], na: int):
    """``(q̈, [w_c], τ)`` of ``x``, and the world wrenches ``W_c = diag(R_c, R_c) w_c``."""
    wrenches = [x[sl] for sl in slices]
    world = [world_wrench(c.rows.rotation, w) for c, w in zip(contacts, wrenches, strict=True)]
    return x[:NV], wrenches, x[len(x) - na :], world


CASES = [((6, 6), (3, 6)), ((6,), (2,)), ((), (4,)), ((3, 6), ()), ((6, 3, 3), (1, 1))]


@pytest.mark.parametrize("kinds, task_rows", CASES)
def test_the_rows_are_the_equations_of_motion_contacts_and_tasks(kinds, task_rows, rng):
    """On random states and random ``x``: level 0's residual is ``M q̈ + h − B τ − Σ J_cᵀ W_c``; the
    contacts' level is ``J_c q̈ − a_c`` then ``A_c w_c ≤ 0``; each task's level is its rows over
    ``q̈`` alone; the last level damps ``q̈`` towards ``−K_d v``."""
    for _ in range(5):
        terms, contacts, tasks = random_problem(rng, kinds, task_rows)
        gain = rng.uniform(0.0, 20.0)
        levels, slices = dynamic_rows(terms, contacts, tasks, gain)
        assert slices == wrench_slices(NV, contacts)
        na = terms.B.shape[1]
        x = rng.standard_normal(levels[0][0].shape[1])
        qdd, wrenches, tau, world = split(x, contacts, slices, na)
        A, lower, upper = levels[0]
        assert lower is upper
        motion = terms.M @ qdd + terms.h - terms.B @ tau - sum((c.rows.jacobian.T @ W for c, W in zip(contacts, world, strict=True)),
                                                                 np.zeros(NV))
        np.testing.assert_allclose(A @ x - lower, motion, rtol=1e-12, atol=1e-9)
        rest = levels[1:]
        if contacts:
            (A, lower, upper), rest = rest[0], rest[1:]
            n_w = sum(len(w) for w in wrenches)
            expected = np.concatenate([c.rows.jacobian @ qdd - c.rows.acceleration for c in contacts])
            np.testing.assert_allclose(A[:n_w] @ x - lower[:n_w], expected, rtol=1e-12, atol=1e-12)
            np.testing.assert_array_equal(upper[:n_w], lower[:n_w])
            inequalities = np.concatenate([c.rows.wrench_rows @ w for c, w in zip(contacts, wrenches, strict=True)])
            np.testing.assert_allclose(A[n_w:] @ x, inequalities, rtol=1e-12, atol=1e-12)
            assert np.all(lower[n_w:] == -np.inf) and np.all(upper[n_w:] == 0.0)
        for task, (A, lower, upper) in zip(tasks, rest[:-1], strict=True):
            np.testing.assert_allclose(A @ x, task.jacobian @ qdd, rtol=1e-12, atol=1e-12)
            assert lower is task.lower and upper is task.upper
        A, lower, upper = rest[-1]
        np.testing.assert_allclose(A[:NV] @ x, qdd, rtol=0, atol=0)
        np.testing.assert_allclose(lower[:NV], -gain * terms.v, rtol=1e-15)
        assert np.all(lower[NV:] == 0.0)


@pytest.mark.parametrize("kinds", [(6, 6), (6, 3), ()])
def test_torques_eliminated_give_back_the_equations_of_motion(kinds, rng):
    """With ``τ`` eliminated (``B`` a selection), the dynamics level keeps the unactuated rows and
    :func:`torques_of` gives the ``τ`` that makes every row of the equations of motion hold."""
    terms, contacts, tasks = random_problem(rng, kinds, (3,))
    actuated = actuated_rows(terms.B)
    np.testing.assert_array_equal(actuated, np.arange(6, NV))
    reduced, slices = dynamic_rows(terms, contacts, tasks, 5.0, False, None, actuated)
    y = rng.standard_normal(reduced[0][0].shape[1])
    tau = torques_of(terms, contacts, slices, y, actuated)
    full, _ = dynamic_rows(terms, contacts, tasks, 5.0, False)
    x = np.concatenate([y, tau])
    residual = full[0][0] @ x - full[0][1]
    np.testing.assert_allclose(residual[unactuated_rows(NV, actuated)], reduced[0][0] @ y - reduced[0][1], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(residual[6:], 0.0, atol=1e-9 * np.abs(terms.h).max())
    assert actuated_rows(np.ones((NV, 2))) is None  # not a selection: τ stays an unknown


def test_the_bounds_hold_the_limits_the_forces_and_the_efforts(rng):
    terms, contacts, _ = random_problem(rng, (6, 3), ())
    contacts[1] = ActiveContact(contacts[1].name, contacts[1].rows, f_max=12.0, f_low=20.0)  # being released
    slices = wrench_slices(NV, contacts)
    a_lower, a_upper = -rng.uniform(1, 5, NV), rng.uniform(1, 5, NV)
    effort = rng.uniform(10, 100, NV - 6)
    lower, upper = variable_bounds(NV, contacts, slices, a_lower, a_upper, effort)
    n = NV + 9 + NV - 6
    assert lower.shape == upper.shape == (n,)
    np.testing.assert_array_equal(lower[:NV], a_lower)
    np.testing.assert_array_equal(upper[:NV], a_upper)
    np.testing.assert_array_equal(lower[n - 6 - (NV - 12):], -effort)
    np.testing.assert_array_equal(upper[n - 6 - (NV - 12):], effort)
    held, released = slices[0].stop - 1, slices[1].stop - 1  # the normal forces f_z
    assert (lower[held], upper[held]) == (30.0, np.inf)
    assert (lower[released], upper[released]) == (12.0, 12.0)  # the ramp's lower bound never above its upper one
    assert normal_force_limits(contacts, slices) == [(held, 30.0, np.inf), (released, 12.0, 12.0)]
    others = np.setdiff1d(np.arange(NV, NV + 9), [held, released])
    assert np.all(lower[others] == -np.inf) and np.all(upper[others] == np.inf)
    start = inside(lower, upper)
    assert np.all(lower <= start) and np.all(start <= upper)
    assert start[held] == 30.0 and np.all(start[:NV] == 0.0)


def test_shear_weights_share_the_tangential_force_in_proportion_to_the_loads():
    weights = shear_weights(np.array([400.0, 100.0]), 2)
    np.testing.assert_allclose(weights, [np.sqrt(250 / 400), np.sqrt(250 / 100)])
    np.testing.assert_array_equal(shear_weights(None, 2), [1.0, 1.0])
    np.testing.assert_array_equal(shear_weights(np.array([np.nan, 100.0]), 2), [1.0, 1.0])
    assert np.isfinite(shear_weights(np.array([0.0, 800.0]), 2)).all()


def test_torques_of_is_drakes_inverse_dynamics_with_a_held_sole(talos_model, rng):
    """``τ = (M q̈ + h − J_cᵀ W_c)`` on the actuated rows is what Drake's inverse dynamics gives
    with gravity and the contact's wrench applied at the sole frame's origin, on random states."""
    model = talos_model
    plant = model.plant
    context = plant.CreateDefaultContext()
    B = plant.MakeActuationMatrix()
    actuated = actuated_rows(B)
    assert actuated is not None
    frame = model.frame("left-sole")
    world = plant.world_frame()
    for _ in range(3):
        q = random_configuration(model, rng, 0.2)
        v = rng.normal(scale=0.5, size=model.nv)
        plant.SetPositions(context, q)
        plant.SetVelocities(context, v)
        M = plant.CalcMassMatrix(context)
        h = plant.CalcBiasTerm(context) - plant.CalcGravityGeneralizedForces(context)
        J = plant.CalcJacobianSpatialVelocity(context, JacobianWrtVariable.kV, frame, np.zeros(3), world, world)
        R = plant.CalcRelativeRotationMatrix(context, world, frame).matrix()
        terms = DynamicsTerms(M, h, plant.CalcBiasTerm(context), B, q, v, plant.CalcTotalMass(context))
        contact = ActiveContact("left", ContactRows(J, np.zeros(6), R, wrench_constraints(0.7, SOLE, 0.01), 30.0, 0.7))
        qdd, w = rng.normal(size=model.nv), np.concatenate([rng.normal(scale=20, size=5), [400.0]])
        y = np.concatenate([qdd, w])
        tau = torques_of(terms, [contact], wrench_slices(model.nv, [contact]), y, actuated)
        forces = MultibodyForces(plant)
        plant.CalcForceElementsContribution(context, forces)
        forces.mutable_generalized_forces()[:] += J.T @ world_wrench(R, w)
        drake = plant.CalcInverseDynamics(context, qdd, forces)
        damping = np.zeros(model.nv)
        for index in plant.GetJointIndices():
            joint = plant.get_joint(index)
            damping[joint.velocity_start() : joint.velocity_start() + joint.num_velocities()] = joint.default_damping_vector()
        expected = (drake - damping * v)[actuated] if np.any(damping) else drake[actuated]
        np.testing.assert_allclose(tau, expected, rtol=1e-9, atol=1e-8 * np.abs(drake).max())
        assert Layout.of(plant).base_v is not None  # a floating base: its rows are not torques
