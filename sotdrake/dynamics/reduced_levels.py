"""``SolverDyn``'s fast path assembled in one compiled call: the levels with ``τ`` eliminated,
stacked as the QR path takes them, the bounds on ``x``, and the checks of the optimum.

The maths is :mod:`.formulation`'s (:func:`~.formulation.dynamic_rows` with ``actuated``,
:func:`~.formulation.variable_bounds`, :func:`~.formulation.torques_of`), which stays the reference
(the tests compare them) and the path of everything this one does not cover: the full problem over
``(q̈, w, τ)`` and stacks with inequality tasks. Here the contacts' and tasks' arrays are stacked
(a few numpy calls) and handed to :mod:`.jit_reduced_levels` (numba; compiled once after an install).
"""

from __future__ import annotations

import itertools
from functools import cache

import numpy as np

from ..compiled import compiled_input, kernels, read_only
from ..hqp.equality_hierarchy import StackedLevels
from ..task import TaskLevel
from .formulation import ActiveContact
from .terms import DynamicsTerms

WRENCH_ROW_TOLERANCE = 1e-9  # as formulation._wrench_rows_hold
_NO_SELECTION = np.ones(0, dtype=bool)


_compiled = kernels(".jit_reduced_levels", __package__, "reduced_stack", "the dynamic solver's assembly", "a few seconds")


@cache
def _sizes(sizes: tuple[int, ...]) -> np.ndarray:
    return read_only(np.array(sizes, dtype=np.int64))


class StackedContacts:
    """The active contacts' arrays stacked (see :mod:`.jit_reduced_levels`): ``JT`` (their Jacobians,
    transposed side by side: nv × Σk), ``RT`` (their rotations transposed side by side, 3 × 3c),
    ``acceleration``; and what changes only with the contact set
    (:func:`_contact_set`): ``sizes`` (6, or 3 for a point contact), ``offsets`` (where each wrench
    starts after q̈, and their total), ``centres`` (c × 2), ``wrench_rows`` (stacked, padded to 6
    columns) and ``row_counts``."""

    def __init__(self, contacts: list[ActiveContact], nv: int):
        rows = [c.rows for c in contacts]
        self.sizes, self.offsets, self.centres, self.wrench_rows, self.row_counts = _contact_set(rows)
        # Drake's Jacobians and rotations are column-major: their transposes are C-ordered views.
        if len(rows) > 1:
            self.JT = compiled_input(np.concatenate([r.jacobian.T for r in rows], axis=1))
            self.RT = compiled_input(np.concatenate([r.rotation.T for r in rows], axis=1))
            self.acceleration = compiled_input(np.concatenate([r.acceleration for r in rows]))
        elif rows:
            self.JT, self.RT = compiled_input(rows[0].jacobian.T), compiled_input(rows[0].rotation.T)
            self.acceleration = compiled_input(rows[0].acceleration)
        else:
            self.JT, self.RT, self.acceleration = np.zeros((nv, 0)), np.zeros((3, 0)), np.zeros(0)


#: :func:`_contact_set`'s cache, keyed on the contacts' wrench-row arrays by identity (each entry
#: holds them, so an identity is not reused while it is there), their centres and sizes.
_CONTACT_SETS: dict[tuple, tuple] = {}


def _contact_set(rows: list) -> tuple[np.ndarray, list[int], np.ndarray, np.ndarray, np.ndarray]:
    """``(sizes, offsets, centres, wrench_rows, row_counts)`` of :class:`StackedContacts`, read-only,
    cached: the contacts' wrench rows are the same arrays from one tick to the next
    (:func:`.contact.wrench_constraints` caches them)."""
    key = tuple((id(r.wrench_rows), r.centre, r.jacobian.shape[0]) for r in rows)
    found = _CONTACT_SETS.get(key)
    if found is None:
        if len(_CONTACT_SETS) >= 64:
            _CONTACT_SETS.clear()
        sizes = tuple(r.jacobian.shape[0] for r in rows)
        blocks = [np.pad(np.asarray(r.wrench_rows, dtype=float), ((0, 0), (0, 6 - r.wrench_rows.shape[1]))) for r in rows]
        arrays = (_sizes(sizes), [0, *itertools.accumulate(sizes)],
                  read_only(np.array([r.centre for r in rows], dtype=float).reshape(len(rows), 2)),
                  read_only(np.concatenate(blocks) if blocks else np.zeros((0, 6))), _sizes(tuple(len(r.wrench_rows) for r in rows)))
        found = _CONTACT_SETS[key] = (tuple(r.wrench_rows for r in rows), arrays)
    return found[1]


def reduced_stack(terms: DynamicsTerms, contacts: StackedContacts, tasks: list[TaskLevel], damping_gain: float,
                  scales: list[float], passive: np.ndarray) -> StackedLevels:
    """:func:`~.formulation.dynamic_rows` with ``τ`` eliminated (``passive``: the unactuated rows, an
    int64 index array), every task an equality, stacked: the dynamics, the contacts (when there are
    some), the tasks, the damping level whose regularization rows of contact c are scaled by
    ``scales[c]`` (``WRENCH_REGULARIZATION`` × its shear weight)."""
    nv = terms.M.shape[0]
    if tasks:
        task_J = compiled_input(np.concatenate([t.jacobian for t in tasks]) if len(tasks) > 1 else tasks[0].jacobian)
        task_rhs = compiled_input(np.concatenate([t.lower for t in tasks]) if len(tasks) > 1 else tasks[0].lower)
    else:
        task_J, task_rhs = np.zeros((0, nv)), np.zeros(0)
    A, b, norms, starts = _compiled().reduced_stack(
        compiled_input(terms.M), compiled_input(terms.h), passive, contacts.JT, contacts.RT, contacts.sizes,
        contacts.acceleration, contacts.centres, np.array(scales, dtype=float), task_J, task_rhs,
        _sizes(tuple(len(t.lower) for t in tasks)), compiled_input(terms.v), float(damping_gain))
    return StackedLevels(A, b, norms, starts)


def torques_and_checks(terms: DynamicsTerms, contacts: StackedContacts, actuated: np.ndarray, x: np.ndarray,
                       effort: np.ndarray) -> tuple[np.ndarray, list[np.ndarray], bool, bool]:
    """``(τ, world wrenches, within, hold)`` at ``x = (q̈, w…)`` (:func:`~.formulation.torques_of`;
    ``within``: ``|τ| ≤ effort``; ``hold``: the contacts' wrench rows hold, as
    :func:`~.formulation._wrench_rows_hold`)."""
    tau, world, within, hold = _compiled().torques_and_checks(
        compiled_input(terms.M), compiled_input(terms.h), actuated, contacts.JT, contacts.RT, contacts.sizes,
        compiled_input(x), effort, contacts.wrench_rows, contacts.row_counts, WRENCH_ROW_TOLERANCE)
    offsets = contacts.offsets
    return tau, [world[offsets[i] : offsets[i + 1]] for i in range(len(offsets) - 1)], bool(within), bool(hold)


def bounds(lower_template: np.ndarray, upper_template: np.ndarray, q: np.ndarray, v: np.ndarray, joints_q: np.ndarray,
           joints_v: np.ndarray, position_limits: np.ndarray, velocity_limits: np.ndarray, horizon: float, margin: float,
           dt: float, braking: np.ndarray, selection: np.ndarray | None, normal: list[tuple[int, float, float]]
           ) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`~.solver_dyn.SolverDyn._bounds` compiled (:func:`.jit_reduced_levels.dynamic_bounds`):
    the components out of the control ``selection`` (a boolean mask over the first ones; None:
    every component controlled) fixed at 0, ``normal`` the normal forces' ``(index, lower, upper)``.
    ``joints_q``, ``joints_v``: int64 index arrays; ``braking``: each joint's torque braking (inf: none)."""
    index = np.array([i for i, _, _ in normal], dtype=np.int64)
    return _compiled().dynamic_bounds(
        lower_template, upper_template, compiled_input(q), compiled_input(v), joints_q, joints_v, position_limits,
        velocity_limits, float(horizon), float(margin), float(dt), braking,
        _NO_SELECTION if selection is None else compiled_input(selection, bool), index, np.array([lo for _, lo, _ in normal], dtype=float),
        np.array([hi for _, _, hi in normal], dtype=float))
