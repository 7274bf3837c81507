"""SolverDyn's compiled fast path (:mod:`sotdrake.dynamics.reduced_levels`) against the Python
references it replaces on the tick: :func:`dynamic_rows` with τ eliminated, :func:`torques_of`,
the wrench rows' check and the effort check, on random problems with sole and point contacts."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sotdrake.dynamics.contact import ContactRows, wrench_constraints
from sotdrake.dynamics.formulation import (
    WRENCH_REGULARIZATION,
    ActiveContact,
    _shear_weights,
    _wrench_rows_hold,
    actuated_rows,
    dynamic_rows,
    torques_of,
    unactuated_rows,
    wrench_slices,
)
from sotdrake.dynamics.reduced_levels import StackedContacts, reduced_stack, torques_and_checks
from sotdrake.dynamics.terms import DynamicsTerms
from sotdrake.hqp.equality_hierarchy import StackedLevels
from sotdrake.task import TaskLevel

NV = 14
SOLE = (-0.1, 0.12, -0.05, 0.06)


def _problem(rng: np.random.Generator, kinds: tuple[int, ...], task_rows: tuple[int, ...]):
    """Random terms over a floating base (6 passive rows) and NV − 6 actuated joints, contacts of
    the given sizes (6: a sole, 3: a point), equality tasks with the given rows."""
    L = rng.standard_normal((NV, NV))
    B = np.zeros((NV, NV - 6))
    B[6:] = np.eye(NV - 6)
    B.flags.writeable = False
    terms = DynamicsTerms(L @ L.T + NV * np.eye(NV), 100 * rng.standard_normal(NV), rng.standard_normal(NV), B,
                          rng.standard_normal(NV + 1), rng.standard_normal(NV), 50.0)
    contacts = []
    for i, k in enumerate(kinds):
        rectangle = SOLE if k == 6 else None
        rotation = Rotation.random(random_state=rng.integers(1 << 30)).as_matrix()
        rows = ContactRows(rng.standard_normal((k, NV)), rng.standard_normal(k), rotation,
                           wrench_constraints(0.7, rectangle, 0.01), 30.0, 0.7,
                           (0.0, 0.0) if k == 3 else ((SOLE[0] + SOLE[1]) / 2, (SOLE[2] + SOLE[3]) / 2))
        contacts.append(ActiveContact(f"contact{i}", rows))
    tasks = []
    for m in task_rows:
        rhs = rng.standard_normal(m)
        tasks.append(TaskLevel(rng.standard_normal((m, NV)), rhs, rhs, rhs))
    return terms, contacts, tasks


CASES = [((6, 6), (3, 32 % NV, 6)), ((6,), (3,)), ((), (2, 5)), ((3, 6), (4,)), ((6, 3, 3), ()), ((3,), (1, 1, 1))]


@pytest.mark.parametrize("kinds, task_rows", CASES)
def test_the_compiled_stack_is_dynamic_rows_with_torques_eliminated(kinds, task_rows, rng):
    for trial in range(5):
        terms, contacts, tasks = _problem(rng, kinds, task_rows)
        loads = rng.uniform(0.0, 500.0, len(kinds)) if trial % 2 else None
        actuated = actuated_rows(terms.B)
        passive = np.arange(NV, dtype=np.int64)[unactuated_rows(NV, actuated)]
        np.testing.assert_array_equal(passive, np.arange(6))
        gain = rng.uniform(0.0, 20.0)
        scales = [WRENCH_REGULARIZATION * w for w in _shear_weights(loads, len(contacts))]
        got = reduced_stack(terms, StackedContacts(contacts, NV), tasks, gain, scales, passive)
        levels, _ = dynamic_rows(terms, contacts, tasks, gain, False, loads, actuated)
        want = StackedLevels.of([(A, b) for A, b, _ in levels])
        np.testing.assert_array_equal(got.starts, want.starts)
        p = len(passive)
        scale = np.abs(want.A[:p]).max()
        np.testing.assert_allclose(got.A[:p], want.A[:p], rtol=0, atol=1e-13 * scale)  # −J_cᵀ diag(R, R): sums of 3
        np.testing.assert_array_equal(got.A[p:], want.A[p:])  # copies and the weighted template: exact
        np.testing.assert_array_equal(got.b, want.b)
        np.testing.assert_allclose(got.norms, want.norms, rtol=1e-14)
        for array in got:
            assert array.flags.c_contiguous and array.flags.writeable


@pytest.mark.parametrize("kinds", [(6, 6), (6,), (3, 6), (3,), ()])
def test_the_compiled_torques_and_checks_are_the_references(kinds, rng):
    seen = set()
    for trial in range(20):
        terms, contacts, _ = _problem(rng, kinds, ())
        actuated = actuated_rows(terms.B)
        slices = wrench_slices(NV, contacts)
        x = rng.standard_normal(NV + sum(kinds))
        for sl in slices:
            w = x[sl]
            w[-1] = 100.0  # a normal force; the shear and moments within the rows or, on odd trials, some not
            w[:-1] *= 1e-3 if trial % 2 == 0 else 50.0
        effort = rng.uniform(10.0, 2000.0, NV - 6)
        tau, world, within, hold = torques_and_checks(terms, StackedContacts(contacts, NV), actuated.astype(np.int64), x, effort)
        reference = torques_of(terms, contacts, slices, x, actuated)
        np.testing.assert_allclose(tau, reference, rtol=0, atol=1e-12 * np.abs(reference).max())
        for W, c, sl in zip(world, contacts, slices, strict=True):
            R = c.rows.rotation
            expected = R @ x[sl] if len(W) == 3 else np.concatenate([R @ x[sl][:3], R @ x[sl][3:]])
            np.testing.assert_allclose(W, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
        assert within == bool(np.all(np.abs(reference) <= effort))
        assert hold == _wrench_rows_hold(contacts, slices, x)
        seen.add(hold)
    assert seen == ({True, False} if kinds else {True})  # both answers were compared


def test_a_violated_wrench_row_or_torque_is_caught(rng):
    terms, contacts, _ = _problem(rng, (6, 3), ())
    actuated = actuated_rows(terms.B).astype(np.int64)
    x = np.zeros(NV + 9)
    x[NV + 5] = x[NV + 8] = 100.0  # both normal forces, no shear: every row holds
    stacked = StackedContacts(contacts, NV)
    effort = np.full(NV - 6, 1e6)
    assert torques_and_checks(terms, stacked, actuated, x, effort)[2:] == (True, True)
    for index in (NV + 3, NV + 6):  # a shear beyond the pyramid: on the sole, then on the point contact
        y = x.copy()
        y[index] = 80.0
        assert torques_and_checks(terms, stacked, actuated, y, effort)[2:] == (True, False)
    tau = torques_and_checks(terms, stacked, actuated, x, effort)[0]
    small = np.abs(tau) * (1 + 1e-12)
    small[3] = abs(tau[3]) * 0.99
    assert torques_and_checks(terms, stacked, actuated, x, small)[2:] == (False, True)


def test_the_compiled_bounds_are_the_joint_limits_as_acceleration_bounds_exactly(rng):
    """:func:`reduced_levels.bounds` against :func:`acceleration_bounds` and :func:`variable_bounds`
    (bit for bit), joints inside, on and beyond their limits, moving both ways, some held by the
    control selection, a contact held and one being released."""
    from sotdrake.configuration import Layout
    from sotdrake.dynamics.formulation import normal_force_limits, variable_bounds
    from sotdrake.dynamics.reduced_levels import bounds
    from sotdrake.dynamics.terms import acceleration_bounds, stacked_limits

    joints = NV - 6
    layout = Layout(0, 0, np.arange(7, 7 + joints), np.arange(6, NV))
    iq, iv = layout.joints_q, layout.joints_v
    terms, contacts, _ = _problem(rng, (6, 6), ())
    contacts[1].f_max, contacts[1].f_low = 120.0, 12.0
    slices = wrench_slices(NV, contacts)
    effort = rng.uniform(10.0, 100.0, joints)
    for _ in range(20):
        lower_q = rng.uniform(-2.0, 0.0, NV + 1)
        upper_q = lower_q + rng.uniform(0.1, 3.0, NV + 1)
        upper_v = rng.uniform(0.5, 5.0, NV)
        q = rng.uniform(lower_q - 0.2, upper_q + 0.2)
        q[iq[:3]] = upper_q[iq[:3]] - rng.uniform(0.0, 2e-3, 3)  # inside the margin
        v = rng.uniform(-6.0, 6.0, NV)
        horizon, margin, dt = rng.uniform(0.01, 0.2), rng.uniform(0.0, 0.01), rng.choice([1e-3, 5e-3, 1e-2])
        selection = rng.random(NV) > 0.2
        braking = rng.uniform(1.0, 200.0, NV)  # torque braking: below v_max/T for some joints, above for others
        braking[rng.random(NV) < 0.3] = np.inf  # (and none for some)
        upper_v[rng.random(NV) < 0.1] = np.inf  # (a joint without a velocity limit)
        lower_q[rng.random(NV + 1) < 0.1] = -np.inf  # (joints without a position limit, on one side or both)
        upper_q[rng.random(NV + 1) < 0.1] = np.inf
        a_lo, a_up = acceleration_bounds(q, v, lower_q, upper_q, -upper_v, upper_v, horizon, margin, layout, dt=dt,
                                         braking=braking)
        a_lo[~selection] = a_up[~selection] = 0.0
        want = variable_bounds(NV, contacts, slices, a_lo, a_up, effort)
        n = len(want[0])
        free = np.full(n - joints, np.inf)
        templates = np.concatenate((-free, -effort)), np.concatenate((free, effort))
        got = bounds(*templates, q, v, iq.astype(np.int64), iv.astype(np.int64),
                     *stacked_limits(lower_q[iq], upper_q[iq], -upper_v[iv], upper_v[iv]), horizon, margin, dt,
                     np.ascontiguousarray(braking[iv]), selection,
                     normal_force_limits(contacts, slices))
        for g, w in zip(got, want, strict=True):
            np.testing.assert_array_equal(g, w)
            assert not np.isnan(g).any()
