"""The inverse-dynamics formulation of :class:`~.solver_dyn.SolverDyn`, as pure functions.

Unknowns: the generalized acceleration ``q̈`` (nv), each active contact's local wrench ``w_c``
(6, or 3 for a point contact; see :mod:`.contact`) and the actuator torques ``τ`` (na, actuator
order). Hard bounds on ``x`` (never violated): the joint limits as acceleration bounds
(:func:`.terms.acceleration_bounds`), ``|τ| ≤`` the effort limits, and each normal force
``f_min ≤ f_z ≤ f_max`` (``f_max`` finite only while the contact is released). The levels, highest
first (:func:`dynamic_rows`):

0. the dynamics ``M q̈ − Σ J_cᵀ diag(R_c, R_c) w_c − B τ = −h`` (exact: it is physics);
1. the contacts: ``J_c q̈ = −J̇_c v`` (zero acceleration) with the friction, CoP and yaw rows
   ``A_c w_c ≤ 0``;
2. … the user's stack (``push``), each a :class:`~sotdrake.task.TaskLevel` over ``q̈``
   (``TaskDynPD``);
last. ``q̈ = −K_d v``: whatever motion the stack leaves free is damped (``setDampingGain``); in
   the same level, a regularization of the contact wrenches (:func:`wrench_regularization`) so that
   the distribution the levels above leave free keeps away from the friction and CoP bounds, *in
   proportion to the normal forces*: ``ε √(f̄/f_c) (n_x − y_c f_z, n_y + x_c f_z, n_z, f_x, f_y) = 0``
   (``ε = 10⁻³`` s²/kg·m, ``(x_c, y_c)`` the sole's centre, ``f_c`` the normal force contact c
   carried at the previous tick, ``f̄`` their mean). Minimizing ``Σ_c ‖f_t,c‖²/f_c`` under
   ``Σ_c f_t,c = F_t`` gives ``f_t,c = F_t f_c/Σ f``: every contact uses the same fraction of its
   friction cone; likewise ``Σ_c f_c d_c²`` (``d_c`` the CoP's offset from the sole's centre)
   gives every sole the same CoP offset. With the rows unweighted, the shear and the moments are
   shared *equally*: at the sway's extremes the nearly unloaded sole (40 N) carried half of the
   45 N of lateral force, at the edge of its friction pyramid, and half of the moment, its CoP at
   the edge of the sole; on the physics plant it rolled on that edge and slipped.

With ``B`` a selection (:func:`actuated_rows`), ``τ`` can be eliminated: the levels over ``(q̈, w)``
keep the unactuated rows of the dynamics, and :func:`torques_of` gives ``τ`` back (the actuated
rows of ``M q̈ + h − Σ_c J_cᵀ W_c``). Joints without an actuator would get no ``τ`` column: TALOS'
loaded models actuate every joint (the loader adds the differential joints' actuators), so ``B``
is a permutation of the joint rows; a model with unactuated joints keeps them passive through the
dynamics rows.

No system, no state: these functions take the terms and return rows, bounds and torques.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..compiled import read_only
from ..configuration import contiguous_slice
from ..hqp import LevelRows
from ..task import TaskLevel
from .contact import ContactRows, local_to_generalized, world_wrench
from .terms import DynamicsTerms

#: ε of the wrench regularisation (s²/kg·m): its rows weigh this much against ``q̈`` in the last level.
WRENCH_REGULARIZATION = 1e-3
#: The contacts' level counts as missed above this slack (m/s², rad/s²; relative above a reference of 1).
CONTACT_SLACK = 1e-6
#: The dynamics level counts as missed above this residual (N·m, N; relative to ``max(1, ‖h‖)``).
DYNAMICS_SLACK = 1e-6
#: How many bounds at the optimum the solver remembers from one tick to the next.
HELD_BOUNDS = 8


@dataclass
class ActiveContact:
    """A contact the solver holds at this tick: its name, its rows (:class:`.contact.ContactRows`)
    and, while released, the ramp's bounds on its normal force (N)."""

    name: str
    rows: ContactRows
    f_max: float = np.inf  # the release ramp's bounds on the normal force: upper,
    f_low: float = 0.0  # and lower (used when f_max is finite)


def shear_weights(loads: np.ndarray | None, count: int) -> np.ndarray:
    """The factor ``√(f̄/f_c)`` of each contact's shear regularization (see the module docstring)
    from the normal forces ``loads`` (N) the contacts carried at the previous tick; ones if there
    is no such record (NaN: a new contact) or a single contact. Each load is floored at 1 % of the
    mean (and 1 N), so a contact that carried nothing gets a large, finite weight."""
    return np.array(_shear_weights(loads, count))


def _shear_weights(loads: np.ndarray | list[float] | None, count: int) -> list[float]:
    """:func:`shear_weights` as Python floats (a few contacts: cheaper than numpy calls)."""
    if loads is None or count < 2:
        return [1.0] * count
    values = [float(f) for f in loads] if isinstance(loads, list) else np.asarray(loads, dtype=float).ravel().tolist()
    if len(values) != count or (not isinstance(loads, list) and np.ndim(loads) != 1):
        return [1.0] * count
    if not all(math.isfinite(f) for f in values):
        return [1.0] * count
    mean = max(sum(max(f, 0.0) for f in values) / count, 1.0)
    floor = max(0.01 * mean, 1.0)
    return [math.sqrt(mean / max(f, floor)) for f in values]


def wrench_regularization(contact: ActiveContact, k: int, weight: float) -> np.ndarray:
    """The regularization rows of one contact's wrench (k = 6: ``(n, f)``; 3: ``f``), target 0,
    all scaled by ``weight``: the CoP's offset from the sole's centre ``(x_c, y_c)`` times ``f_z``,
    the yaw torque and the shear."""
    return WRENCH_REGULARIZATION * weight * _regularization_rows(tuple(contact.rows.centre) if k == 6 else None)


@lru_cache(maxsize=32)
def _regularization_rows(centre: tuple[float, float] | None) -> np.ndarray:
    """The unweighted rows of :func:`wrench_regularization` (None: a point contact's force),
    read-only and cached: asked at every tick."""
    if centre is None:
        rows = np.eye(3)[:2]
    else:
        rows = np.zeros((5, 6))
        rows[0, 0], rows[0, 5] = 1.0, -centre[1]  # n_x − y_c f_z: the CoP's y offset × f_z
        rows[1, 1], rows[1, 5] = 1.0, centre[0]  # n_y + x_c f_z: minus its x offset × f_z
        rows[2, 2] = rows[3, 3] = rows[4, 4] = 1.0  # n_z, f_x, f_y
    rows.flags.writeable = False
    return rows


def inside(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The point of the box ``[lower, upper]`` nearest 0: where the hierarchical QP starts, so that
    every bound holds (it keeps a start that violates a bound where it is, see
    :meth:`HierarchicalQP.solve`): ``f_z ≥ f_min > 0`` excludes ``x = 0``."""
    return np.minimum(np.maximum(0.0, lower), upper)


def wrench_slices(nv: int, contacts: list[ActiveContact]) -> list[slice]:
    """Where each contact's wrench lies in ``x = (q̈, w…, τ)``."""
    slices, start = [], nv
    for c in contacts:
        k = c.rows.jacobian.shape[0]
        slices.append(slice(start, start + k))
        start += k
    return slices


Rows = tuple[np.ndarray, np.ndarray, np.ndarray]  # (A, lower, upper) of one level; lower is upper: equalities


def dynamic_levels(
    terms: DynamicsTerms, contacts: list[ActiveContact], tasks: list[TaskLevel], damping_gain: float,
    with_inequalities: bool = True, loads: np.ndarray | list[float] | None = None, actuated: np.ndarray | None = None,
) -> tuple[list[LevelRows], list[slice]]:
    """:func:`dynamic_rows` as the hierarchical QP's levels."""
    rows, slices = dynamic_rows(terms, contacts, tasks, damping_gain, with_inequalities, loads, actuated)
    return [LevelRows(*level) for level in rows], slices


def dynamic_rows(
    terms: DynamicsTerms, contacts: list[ActiveContact], tasks: list[TaskLevel], damping_gain: float,
    with_inequalities: bool = True, loads: np.ndarray | list[float] | None = None, actuated: np.ndarray | None = None,
) -> tuple[list[Rows], list[slice]]:
    """The levels of the module docstring over ``x = (q̈, w…, τ)``, and the slice of each contact's
    wrench in ``x``. ``with_inequalities=False`` leaves the contacts' wrench rows out (the
    relaxed problem of :meth:`SolverDyn._calc`); ``loads``: the contacts' normal forces at the
    previous tick (N, for :func:`shear_weights`; None: equal weights). ``actuated`` (from
    :func:`actuated_rows`): ``τ`` eliminated, the levels over ``(q̈, w…)`` with only the
    dynamics' unactuated rows (the actuated ones define ``τ``: :func:`torques_of`).

    What depends only on the sizes (the unactuated rows, the damping level's identity and
    unweighted regularization rows) comes from pure caches (:func:`unactuated_rows`,
    :func:`damping_template`); each tick fills in ``M``, ``h``, the Jacobians and the weights."""
    nv, na = terms.B.shape
    slices = wrench_slices(nv, contacts)
    n_w = slices[-1].stop - nv if slices else 0
    n = nv + n_w + (na if actuated is None else 0)
    passive = unactuated_rows(nv, actuated) if actuated is not None else None
    M, h = (terms.M, terms.h) if passive is None else (terms.M[passive], terms.h[passive])
    dyn = np.empty((M.shape[0], n))
    dyn[:, :nv] = M
    if passive is None:
        dyn[:, nv + n_w :] = -terms.B
    for c, sl in zip(contacts, slices, strict=True):
        J = c.rows.jacobian if passive is None else c.rows.jacobian[:, passive]
        dyn[:, sl] = -local_to_generalized(J, c.rows.rotation)
    b = -h
    levels: list[Rows] = [(dyn, b, b)]
    if contacts:
        m_in = sum(len(c.rows.wrench_rows) for c in contacts) if with_inequalities else 0
        A = np.zeros((n_w + m_in, n))
        lower = np.concatenate([c.rows.acceleration for c in contacts]) if len(contacts) > 1 else contacts[0].rows.acceleration
        if m_in:
            lower = np.concatenate([lower, np.full(m_in, -np.inf)])
            upper = np.concatenate([lower[:n_w], np.zeros(m_in)])
        else:
            upper = lower
        r_in = n_w
        for c, sl in zip(contacts, slices, strict=True):
            A[sl.start - nv : sl.stop - nv, :nv] = c.rows.jacobian
            if m_in:
                m = len(c.rows.wrench_rows)
                A[r_in : r_in + m, sl] = c.rows.wrench_rows
                r_in += m
        levels.append((A, lower, upper))
    for task in tasks:
        A = np.zeros((task.jacobian.shape[0], n))
        A[:, :nv] = task.jacobian
        levels.append((A, task.lower, task.upper))
    template, blocks = damping_template(nv, n, tuple((sl.start, sl.stop, c.rows.centre) for c, sl in zip(contacts, slices, strict=True)))
    damping = template.copy()
    for (rows, columns), weight in zip(blocks, _shear_weights(loads, len(contacts)), strict=True):
        damping[rows, columns] *= WRENCH_REGULARIZATION * weight
    target = np.zeros(len(damping))
    target[:nv] = -damping_gain * terms.v
    levels.append((damping, target, target))
    return levels, slices


@lru_cache(maxsize=16)
def _unactuated_rows(nv: int, actuated: bytes) -> slice | np.ndarray:
    passive = np.ones(nv, dtype=bool)
    passive[np.frombuffer(actuated, dtype=np.intp)] = False
    return _as_slice(np.flatnonzero(passive))


@lru_cache(maxsize=16)
def _index_rows(indices: bytes) -> slice | np.ndarray:
    return _as_slice(np.frombuffer(indices, dtype=np.intp).copy())


def _as_slice(rows: np.ndarray) -> slice | np.ndarray:
    """``rows`` as a slice when contiguous and increasing (:func:`~..configuration.contiguous_slice`),
    else as a read-only index array."""
    as_slice = contiguous_slice(rows)
    return as_slice if as_slice is not None else read_only(rows)


def unactuated_rows(nv: int, actuated: np.ndarray) -> slice | np.ndarray:
    """The velocity rows no actuator drives (a slice when contiguous: TALOS' floating base), from
    :func:`actuated_rows`; a pure cache: the same at every tick."""
    return _unactuated_rows(nv, np.asarray(actuated, dtype=np.intp).tobytes())


def index_rows(indices: np.ndarray) -> slice | np.ndarray:
    """``indices`` (e.g. :func:`actuated_rows`) as a slice when contiguous; a pure cache."""
    return _index_rows(np.asarray(indices, dtype=np.intp).tobytes())


@lru_cache(maxsize=32)
def damping_template(nv: int, n: int, contacts: tuple[tuple[int, int, tuple[float, float]], ...]
                     ) -> tuple[np.ndarray, list[tuple[slice, slice]]]:
    """The last level's rows before weighting, over ``n`` unknowns with the contacts' wrenches at
    ``(start, stop)`` (``centre``: the sole's centre): ``q̈`` (the identity on the first nv columns),
    then each contact's :func:`wrench_regularization` rows unweighted; and where each contact's rows
    are (rows, columns), to be scaled by ``WRENCH_REGULARIZATION`` × its shear weight. Read-only
    and cached (a pure function of the sizes)."""
    m = sum(stop - start - 1 for start, stop, _ in contacts)
    damping = np.zeros((nv + m, n))
    damping.ravel()[: nv * (n + 1) : n + 1] = 1.0
    blocks, row = [], nv
    for start, stop, centre in contacts:
        rows = _regularization_rows(tuple(centre) if stop - start == 6 else None)
        damping[row : row + len(rows), start:stop] = rows
        blocks.append((slice(row, row + len(rows)), slice(start, stop)))
        row += len(rows)
    damping.flags.writeable = False
    return damping, blocks


def actuated_rows(B: np.ndarray) -> np.ndarray | None:
    """The velocity row each actuator drives if ``B`` is a selection (every column a single 1, no
    row driven twice), else None."""
    ones = B == 1.0
    if not (np.all(ones | (B == 0.0)) and np.all(ones.sum(axis=0) == 1) and np.all(ones.sum(axis=1) <= 1)):
        return None
    return np.argmax(ones, axis=0)


def torques_of(terms: DynamicsTerms, contacts: list[ActiveContact], slices: list[slice], y: np.ndarray,
               actuated: np.ndarray | slice, world: list[np.ndarray] | None = None) -> np.ndarray:
    """``τ`` from ``y = (q̈, w…)`` with ``B`` a selection: the actuated rows of
    ``M q̈ + h − Σ_c J_cᵀ W_c``, ``W_c = diag(R_c, R_c) w_c`` the world wrenches (``world``, when
    already computed)."""
    if world is None:
        world = [world_wrench(c.rows.rotation, y[sl]) for c, sl in zip(contacts, slices, strict=True)]
    rows = actuated if isinstance(actuated, slice) else index_rows(actuated)  # a slice for TALOS: views of M, h, J
    tau = terms.M[rows] @ y[: terms.M.shape[0]] + terms.h[rows]
    for c, W in zip(contacts, world, strict=True):
        tau -= c.rows.jacobian[:, rows].T @ W
    return tau


def variable_bounds(
    nv: int, contacts: list[ActiveContact], slices: list[slice], acceleration_lower: np.ndarray,
    acceleration_upper: np.ndarray, effort: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Bounds on ``x``: joint accelerations, the normal forces (``f_min``, the ramp), the torques."""
    start = slices[-1].stop if slices else nv  # where τ starts
    free = np.full(start - nv, np.inf)
    lower = np.concatenate((acceleration_lower, -free, -effort))
    upper = np.concatenate((acceleration_upper, free, effort))
    normal_force_bounds(lower, upper, contacts, slices)
    return lower, upper


def normal_force_bounds(lower: np.ndarray, upper: np.ndarray, contacts: list[ActiveContact], slices: list[slice]) -> None:
    """Write each contact's normal-force bounds (:func:`normal_force_limits`) into the bounds on ``x``."""
    for normal, low, high in normal_force_limits(contacts, slices):
        lower[normal], upper[normal] = low, high


def normal_force_limits(contacts: list[ActiveContact], slices: list[slice]) -> list[tuple[int, float, float]]:
    """Each contact's normal force ``f_z`` (the wrench's last component): ``(index in x, lower, upper)``,
    ``[f_min, ∞)`` while held, the ramp's ``[min(f_low, f_max), f_max]`` while released."""
    out = []
    for c, sl in zip(contacts, slices, strict=False):
        if math.isfinite(c.f_max):
            out.append((sl.stop - 1, min(c.f_low, c.f_max), c.f_max))
        else:
            out.append((sl.stop - 1, c.rows.f_min, math.inf))
    return out


def held_bounds(x: np.ndarray, lower: np.ndarray, upper: np.ndarray, active: np.ndarray) -> np.ndarray:
    """The components ``active`` of ``x`` at a bound, signed: ``i + 1`` at its lower bound, ``−(i + 1)``
    at its upper one, padded with 0 to :data:`HELD_BOUNDS` entries (the first ones kept)."""
    out = np.zeros(HELD_BOUNDS)
    for k, i in enumerate(active[:HELD_BOUNDS].tolist()):  # a few: Python floats cost less than numpy calls
        value = float(x[i])
        out[k] = i + 1.0 if abs(value - float(lower[i])) <= abs(value - float(upper[i])) else -(i + 1.0)
    return out


def _wrench_rows_hold(contacts: list[ActiveContact], slices: list[slice], x: np.ndarray, tolerance: float = 1e-9) -> bool:
    for c, sl in zip(contacts, slices, strict=False):
        w = x[sl]
        A = c.rows.wrench_rows
        if len(A) and np.maximum.reduce(A @ w) > tolerance * max(1.0, float(np.maximum.reduce(np.abs(w)))):
            return False
    return True
