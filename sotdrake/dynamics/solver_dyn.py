"""``SolverDyn`` (sot-dyninv): the stack solved for ``x = (q̈, w_1 … w_k, τ)`` in strict priority.

Unknowns: the generalized acceleration ``q̈`` (nv), each active contact's local wrench ``w_c``
(6, or 3 for a point contact; see :mod:`.contact`) and the actuator torques ``τ`` (na, actuator
order). Hard bounds on ``x`` (never violated): the joint limits as acceleration bounds
(:func:`.terms.acceleration_bounds`), ``|τ| ≤`` the effort limits, and each normal force
``f_min ≤ f_z ≤ f_max`` (``f_max`` finite only while the contact is released). The levels, highest
first (:func:`dynamic_levels`):

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

Solved first with ``τ`` eliminated when ``B`` is a selection (TALOS: every joint actuated):
the actuated rows of the dynamics then only define ``τ``, and the hierarchy over ``(q̈, w)``
keeps the floating base's six rows (``dynamic_levels(..., actuated=...)``, 50 unknowns instead of
82 with both soles). If that optimum's ``τ`` is within the effort limits and the contacts' wrench rows
hold, it is the optimum of the full problem; only otherwise is the full problem solved. With every
task an equality, that fast path is assembled, stacked and checked by compiled code
(:mod:`.reduced_levels`: the same rows as :func:`dynamic_rows`, which stays their definition).

The hierarchical QP then takes the minimum-norm ``x`` of the optimal set (smallest torques and
wrenches among the equivalent ones). Joints without an actuator would get no ``τ`` column: TALOS'
loaded models actuate every joint (the loader adds the differential joints' actuators), so ``B``
is a permutation of the joint rows; a model with unactuated joints keeps them passive through the
dynamics rows.

``rmContact(name, duration)`` releases a contact smoothly: from the first tick after the command,
its normal force's upper bound ramps linearly from the normal force it carried then down to 0 over
``duration`` seconds, and its lower bound from ``f_min`` down to 0 (so the force never jumps: with
the lower bound dropped to 0 at once, a sole held at 30 N went to 0 N in one tick); the contact is removed once the ramp ends, so the
foot lifts off carrying no force. The ramps are discrete state; the contact set is a setting.

Inputs: ``dynamics`` (:class:`.terms.DynamicsTerms`), one per contact (``contact<name>``
ports, :class:`.contact.ContactRows`) and one per task. Outputs: ``control`` (``q̈``, the seed's
name), ``torque`` (τ), ``wrenches`` (the world wrench of each declared contact about its origin,
``(n, f)``, 6 per contact in declaration order, zero when inactive), ``residuals`` (slack norm per
level), ``diagnostics`` and ``stack`` (the names of the tasks in the stack, with the members of a
weighted level (``TaskWeight``) in it: a ``TaskDynPD`` records its Jacobian only while it is there).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import cast

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, InputPort

from ..compiled import read_only
from ..configuration import Layout, contiguous_slice
from ..exceptions import InvalidInput, NotFound, SolverError, StackError, check_number
from ..hqp import ACTIVE_SET, HierarchicalQP, HqpResult, LevelRows, check_solver
from ..hqp.equality_hierarchy import StackedLevels, solve_equality_hierarchy, solve_stacked
from ..hqp.warm import WarmStart, WarmStarts
from ..robots import RobotModel
from ..solvers.sot import SOT, StackSettings
from ..task import TaskLevel
from .checks import MAX_CONTACTS, MAX_DT, MAX_HORIZON, MAX_POSITION_MARGIN, MAX_RATE_GAIN, MAX_RELEASE, check_count, check_positive
from .contact import Contact6d, ContactRows, local_to_generalized, world_wrench
from .reduced_levels import StackedContacts, bounds, reduced_stack, torques_and_checks
from .terms import DynamicsTerms, stacked_limits

log = logging.getLogger("sotdrake.solver_dyn")


WRENCH_REGULARIZATION = 1e-3
#: The contacts' level counts as missed above this slack (m/s², rad/s²; relative above a reference of 1).
CONTACT_SLACK = 1e-6
#: How many bounds at the optimum the solver remembers from one tick to the next.
HELD_BOUNDS = 8


class ContactNotFound(NotFound):
    kind = "contact"


@dataclass
class DynSettings(StackSettings):
    releasing: dict[str, float] = field(default_factory=dict)  # contact name → ramp duration (s)
    damping_gain: float = 10.0  # K_d of the last level (1/s)
    horizon: float = 0.05  # s, joint limits as acceleration bounds
    position_margin: float = 1e-3
    solver: str = ACTIVE_SET


_NO_VALUES, _NO_INDICES = read_only(np.zeros(0)), read_only(np.zeros(0, dtype=int))
_NO_HELD_BOUNDS = read_only(np.zeros(HELD_BOUNDS))


@dataclass
class DynDiagnostics:
    levels: list[str] = field(default_factory=list)
    slack_norms: np.ndarray = field(default_factory=lambda: _NO_VALUES)
    level_solvers: list[str] = field(default_factory=list)
    active_bounds: np.ndarray = field(default_factory=lambda: _NO_INDICES)
    solve_time_s: float = 0.0
    failure: str = ""
    torques_eliminated: bool = False  # solved over (q̈, w) with τ eliminated (the fast path)
    held_bounds: np.ndarray = field(default_factory=lambda: _NO_HELD_BOUNDS)  # see held_bounds()


@dataclass
class DynSolution:
    acceleration: np.ndarray
    torque: np.ndarray
    wrenches: dict[str, np.ndarray]  # world wrench (n, f) of each active contact
    local_wrenches: dict[str, np.ndarray]
    residuals: np.ndarray
    diagnostics: DynDiagnostics

    @property
    def velocity(self) -> np.ndarray:  # what SOT's ``control`` output reads
        return self.acceleration


@dataclass
class ActiveContact:
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


class SolverDyn(SOT):
    """Inverse-dynamics solver with contacts (see the module docstring)."""

    accepts_inequalities = True

    def __init__(self, name: str, model: RobotModel, dt: float, max_contacts: int = 2, damping_gain: float = 10.0,
                 solver: str = ACTIVE_SET, effort_scale: float = 1.0):
        """``effort_scale`` in (0, 1]: the torque bounds are this fraction of the model's effort
        limits (a derated robot; 1: the limits of the URDF)."""
        effort_scale = check_positive(f"{name}: effort_scale", effort_scale, 1.0)  # any real number type, not a bool
        dt = check_positive(f"{name}: dt", dt, MAX_DT, " s")
        max_contacts = check_count(f"{name}: max_contacts", max_contacts, 1, MAX_CONTACTS)
        SOT.__init__(self, name, model.nv, settings=DynSettings())
        self._warned_contacts = False  # logging only (as _warned_scaling): results never depend on it
        self.dt, self.model = dt, model
        self.layout = self._layout = Layout.of(model.plant)
        limits = model.joint_limits()
        self._limits = (limits["position_lower"], limits["position_upper"], limits["velocity_lower"], limits["velocity_upper"])
        iq, iv = self._layout.joints_q, self._layout.joints_v
        # the joints' rows and limits, indexed and stacked once (_bounds: both sides in one evaluation)
        self._joint_indices = (read_only(iq.astype(np.int64)), read_only(iv.astype(np.int64)))
        self._stacked_limits = stacked_limits(self._limits[0][iq], self._limits[1][iq], self._limits[2][iv], self._limits[3][iv])
        self._contact_index: dict[str, int] = {}  # the declaration order of the contacts
        self.effort = limits["effort"] * float(effort_scale)  # |τ| bounds (N·m, N)
        self._effort_held = self.effort * (1 + 1e-9)  # what the fast path's τ must stay within
        self.effort_scale = float(effort_scale)
        self.na = len(self.effort)
        self.max_contacts = max_contacts
        self.setDampingGain(damping_gain)
        self.setSolver(solver)
        self._contact_ports: dict[str, InputPort] = {}
        self._hqps: dict[int, HierarchicalQP] = {}  # a cache of solvers per problem size
        # Their warm starts (which path answers), in the Context, one per problem (see
        # sotdrake.hqp.warm): a cloned or reset Context replays a run bit for bit. The solves update
        # them in place (left out of the solution's prerequisites: nothing is recomputed for them).
        self._warm_index = self.DeclareAbstractState(AbstractValue.Make(WarmStarts()))
        self._actuation: tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray] | None = None  # _actuated_rows
        self._reduced_hqps: dict[int, HierarchicalQP] = {}  # the same, τ eliminated
        self._bound_templates: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # see _bounds
        self.dynamics = self.DeclareAbstractInputPort("dynamics", AbstractValue.Make(
            DynamicsTerms(np.eye(self.nv), np.zeros(self.nv), np.zeros(self.nv), np.zeros((self.nv, self.na)),
                          np.zeros(model.nq), np.zeros(self.nv), 1.0)))
        # Discrete state, one vector (a discrete update is computed from the same context as the
        # device's and the plant's), :meth:`_memory_slices`: the normal force each declared contact
        # carried at the last tick (NaN: not held), which weighs the shear regularization
        # (:func:`shear_weights`); the bounds held at the last tick's optimum (:data:`HELD_BOUNDS`
        # signed entries, see :func:`held_bounds`), where the QR path starts (a guess: the answer does
        # not depend on it); the release ramp of each declared contact, (t0, f0) (NaN: none).
        self._loads, self._held, self._ramps = self._memory_slices(max_contacts)
        memory = np.full(self._ramps.stop, np.nan)
        memory[self._held] = 0.0
        self._memory = self.DeclareDiscreteState(memory)
        self.DeclarePeriodicDiscreteUpdateEvent(self.dt, 0.0, self._update)
        self.DeclareVectorOutputPort("torque", self.na, lambda c, o: o.SetFromVector(self._solution.Eval(c).torque))
        # The names of the tasks in the stack: a TaskDynPD records its Jacobian only while in it.
        self.DeclareAbstractOutputPort("stack", lambda: AbstractValue.Make(()),
                                       lambda c, o: o.set_value(self.solved_tasks(self._settings_of(c))),
                                       prerequisites_of_calc={self.abstract_state_ticket(self._settings_index)})
        self.DeclareVectorOutputPort("wrenches", 6 * max_contacts, self._calc_wrenches)
        self.DeclareAbstractOutputPort("diagnostics", lambda: AbstractValue.Make(DynDiagnostics()),
                                       lambda c, o: o.set_value(self._solution.Eval(c).diagnostics))
        self._built = True  # from now on, setThreshold and setDamping are refused (see below)

    # --- wiring ------------------------------------------------------------------------------
    def declare_contact_input(self, contact: Contact6d) -> InputPort:
        """The input port of ``contact`` (its ``contact`` output goes there)."""
        if contact.name in self._contact_ports:
            return self._contact_ports[contact.name]
        if len(self._contact_ports) == self.max_contacts:
            raise InvalidInput(f"{self.name} was built for {self.max_contacts} contacts (max_contacts)")
        if contact.nv != self.nv:
            raise InvalidInput(f"contact {contact.name} has nv = {contact.nv}, solver {self.name} has nv = {self.nv}")
        port = self.DeclareAbstractInputPort(
            "contact" + contact.name if not contact.name.startswith("contact") else contact.name,
            AbstractValue.Make(ContactRows(np.zeros((6, self.nv)), np.zeros(6), np.eye(3), np.zeros((0, 6)), 0.0, 1.0)),
        )
        self._contact_index[contact.name] = len(self._contact_ports)
        self._contact_ports[contact.name] = port
        return port

    @property
    def known_contacts(self) -> list[str]:
        return list(self._contact_ports)

    def _contact_name(self, contact) -> str:
        name = getattr(contact, "name", contact)
        if not isinstance(name, str) or name not in self._contact_ports:
            raise ContactNotFound(name if isinstance(name, str) else repr(name), list(self._contact_ports))
        return name

    # --- commands ----------------------------------------------------------------------------
    def _settings_of(self, own_context: Context) -> DynSettings:
        return cast(DynSettings, SOT._settings_of(self, own_context))

    def _dyn_command(self, context: Context | None, change: Callable[[DynSettings], None]) -> None:
        self._command(context, cast(Callable[[StackSettings], None], change))

    def addContact(self, contact, context: Context | None = None, priority: str = "top") -> None:
        """Hold ``contact`` (a name or a :class:`Contact6d`); a contact being released is held again.
        A dynamic contact is a constraint of every level: ``priority`` is ``"top"`` only."""
        if priority != "top":
            raise InvalidInput(f"{self.name}.addContact: a dynamic contact constrains every level (priority 'top'), "
                               f"got priority={priority!r}")
        name = self._contact_name(contact)

        def change(s: DynSettings) -> None:
            if name in s.contacts and name not in s.releasing:
                raise StackError(f"{self.name}.addContact: {name!r} is already a contact")
            s.releasing.pop(name, None)
            if name not in s.contacts:
                s.contacts.append(name)

        self._dyn_command(context, change)

    def rmContact(self, contact, duration: float = 0.3, context: Context | None = None) -> None:  # type: ignore[override]
        """Release ``contact``: its normal force ramps to 0 over ``duration`` s (≥ 0), then it is
        removed. Removing the last held contact is refused. (sot-dyninv's ``rmContact``, with the
        ramp's duration: not the kinematic SOT's signature.)"""
        name = self._contact_name(contact)
        duration = check_number(f"{self.name}.rmContact: duration", duration, 0.0, MAX_RELEASE, " s")

        def change(s: DynSettings) -> None:
            held = [c for c in s.contacts if c not in s.releasing]
            if name not in held:
                raise StackError(f"{self.name}.rmContact: {name!r} is not a held contact {held}")
            if len(held) == 1:
                raise StackError(f"{self.name}.rmContact: {name!r} is the last contact; the robot would lose its support")
            if duration == 0:
                log.warning("%s.rmContact(%r, 0): released at once, its load drops in one tick (the robot may tip); "
                            "give a duration > 0 to ramp its force down", self.name, name)
                s.contacts.remove(name)
            else:
                s.releasing[name] = float(duration)

        self._dyn_command(context, change)

    def setDampingGain(self, gain: float, context: Context | None = None) -> None:
        """``K_d`` in [0, :data:`.checks.MAX_RATE_GAIN`] (1/s) of the last level ``q̈ = −K_d v``."""
        value = check_number(f"{self.name}: damping gain K_d", gain, 0.0, MAX_RATE_GAIN, " 1/s")
        self._dyn_command(context, lambda s: setattr(s, "damping_gain", value))

    def setSolver(self, solver: str, context: Context | None = None) -> None:
        check_solver(solver)
        self._dyn_command(context, lambda s: setattr(s, "solver", solver))

    def setJointLimitHorizon(self, horizon: float, margin: float = 1e-3, context: Context | None = None) -> None:
        """Joint limits as acceleration bounds over ``horizon`` s (in (0, :data:`.checks.MAX_HORIZON`]),
        ``margin`` rad (in [0, :data:`.checks.MAX_POSITION_MARGIN`])."""
        values = (check_positive(f"{self.name}: joint-limit horizon", horizon, MAX_HORIZON, " s"),
                  check_number(f"{self.name}: joint-limit margin", margin, 0.0, MAX_POSITION_MARGIN, " rad"))

        def change(s: DynSettings) -> None:
            s.horizon, s.position_margin = values

        self._dyn_command(context, change)

    # The kinematic solvers' settings, which SolverDyn has no use for: refused rather than ignored.
    def setThreshold(self, svd_threshold: float, context: Context | None = None) -> None:
        if getattr(self, "_built", False):
            raise StackError(f"{self.name} is a SolverDyn: its levels are solved exactly (hierarchical QP), it has no SVD "
                             "threshold (setThreshold is the kinematic SOT's)")
        SOT.setThreshold(self, svd_threshold, context)  # SOT.__init__'s default

    def setDamping(self, damping: float, context: Context | None = None) -> None:
        if getattr(self, "_built", False):
            raise StackError(f"{self.name} is a SolverDyn: it has no damped least squares (setDamping is the kinematic "
                             "solvers'); the remaining motion is damped by its last level: setDampingGain")
        SOT.setDamping(self, damping, context)  # SOT.__init__'s default

    def setVelocityLimit(self, limit, context: Context | None = None) -> None:
        raise StackError(f"{self.name} is a SolverDyn: it commands accelerations and torques, not velocities (the joints' "
                         "velocity limits enter its acceleration bounds: setJointLimitHorizon)")

    # --- solve -------------------------------------------------------------------------------
    @staticmethod
    def _memory_slices(max_contacts: int) -> tuple[slice, slice, slice]:
        """Where the loads, the held bounds and the ramps lie in the discrete state."""
        return slice(0, max_contacts), slice(max_contacts, max_contacts + HELD_BOUNDS), \
            slice(max_contacts + HELD_BOUNDS, 3 * max_contacts + HELD_BOUNDS)

    def _ramp(self, context: Context, name: str) -> tuple[float, float]:
        i = self._ramps.start + 2 * self._contact_index[name]
        memory = context.get_discrete_state(self._memory).get_value()
        return float(memory[i]), float(memory[i + 1])

    def held_bound_guess(self, context: Context) -> np.ndarray:
        """The bounds held at the last tick's optimum (:func:`held_bounds`), as recorded in ``context``
        (the solver's own)."""
        return context.get_discrete_state(self._memory).get_value()[self._held].copy()

    def _active_contacts(self, context: Context, s: DynSettings) -> list[ActiveContact]:
        """The held contacts, and the released ones whose ramp has not ended (with their bound)."""
        out = []
        for name in s.contacts:
            f_max, fraction = np.inf, 1.0
            if name in s.releasing:
                t0, f0 = self._ramp(context, name)
                if not np.isnan(t0):
                    fraction = 1.0 - (context.get_time() - t0) / s.releasing[name]
                    if fraction <= 1e-9:
                        continue  # released: the foot is free
                    f_max = max(0.0, f0 * fraction)
            rows = self._contact_ports[name].Eval(context)
            out.append(ActiveContact(name, rows, f_max, rows.f_min * fraction))
        return out

    def held_contacts(self, context: Context) -> list[str]:
        """The contacts the solver uses at the context's time (being released ones included)."""
        own = self.own_context(context)
        return [c.name for c in self._active_contacts(own, self._settings_of(own))]

    def contacts(self, context: Context | None = None) -> list[str]:
        """The contacts as commanded, less those whose release ramp has ended (``rmContact``: then
        the contact is removed). Without a context (the default one), the commanded contacts."""
        if context is None:
            return SOT.contacts(self)
        return self.held_contacts(context)

    def _tasks(self, context: Context, s: DynSettings) -> list[TaskLevel]:
        tasks = []
        for name in s.tasks:
            level = self._task_ports[name].Eval(context)
            J = level.jacobian
            if J.ndim != 2 or J.shape[1] != self.nv or level.lower.shape != (J.shape[0],):
                raise SolverError(f"task {name}: jacobian {J.shape} and bounds {level.lower.shape} do not fit nv = {self.nv}")
            # Squared norms first (sums of squares: NaN only from a NaN, infinite from an infinity or
            # an overflow); only when one is not finite, the elementwise checks.
            entries = J.ravel()
            if not (math.isfinite(entries @ entries) and not math.isnan(level.lower @ level.lower)
                    and (level.upper is level.lower or not math.isnan(level.upper @ level.upper))):
                if (not np.isfinite(J).all() or np.isnan(level.lower).any()
                        or (level.upper is not level.lower and np.isnan(level.upper).any())):
                    raise SolverError(f"task {name}: non-finite jacobian or reference at t = {context.get_time()}")
            tasks.append(level)
        return tasks

    def _calc(self, context: Context, value: AbstractValue) -> None:
        """Solve the hierarchy. First without the contacts' wrench inequalities: every level is then
        an equality (closed forms, no program). If that optimum satisfies those rows it is the
        exact optimum of the full hierarchy too (each level's optimal set with the rows is the one
        without them intersected with the rows, and the optimum lies in it), else the full
        hierarchy is solved."""
        s = self._settings_of(context)
        terms = self.dynamics.Eval(context)
        contacts = self._active_contacts(context, s)
        tasks = self._tasks(context, s)
        loads = self._previous_loads(context, [c.name for c in contacts])
        slices = wrench_slices(self.nv, contacts)
        lower, upper = self._bounds(terms, s, contacts, slices)
        names = ["dynamics"] + (["contacts"] if contacts else []) + list(s.tasks) + ["damping"]
        diagnostics = DynDiagnostics(levels=names)
        n = len(lower)
        hqp = self._hqps.get(n)
        if hqp is None:
            hqp = self._hqps[n] = HierarchicalQP(n)
        warm_starts = context.get_abstract_state(self._warm_index).get_value()
        warm = warm_starts.of(("full", n), n)
        relaxed = result = None
        levels: list[LevelRows] = []
        # The fast path: τ eliminated (a smaller problem, no τ bounds). If its τ is within the
        # effort limits and the wrench rows hold, it is the optimum of the full hierarchy (the same
        # argument as for the wrench rows; after the damping level x is unique, so the last
        # minimum-norm stage changes nothing).
        actuated, compiled_actuated, passive = self._actuated_rows(terms.B)
        if actuated is not None:
            m = n - self.na
            small = self._reduced_hqps.get(m)
            if small is None:
                small = self._reduced_hqps[m] = HierarchicalQP(m)
            small_warm = warm_starts.of(("reduced", m), m)
            try:
                stacked = StackedContacts(contacts, self.nv)
                if all(task.lower is task.upper for task in tasks):  # the levels assembled and stacked compiled
                    scales = [WRENCH_REGULARIZATION * weight for weight in _shear_weights(loads, len(contacts))]
                    stack = reduced_stack(terms, stacked, tasks, s.damping_gain, scales, passive)
                    fast = self._solve_stacked(context, small, stack, lower[:m], upper[:m], s.solver, small_warm)
                else:
                    reduced, _ = dynamic_rows(terms, contacts, tasks, s.damping_gain, False, loads, actuated)
                    fast = self._solve(context, small, reduced, lower[:m], upper[:m], s.solver, small_warm)
                tau, world, within, hold = torques_and_checks(terms, stacked, compiled_actuated, fast.x, self._effort_held)
                if within and hold:
                    fast.x = np.concatenate([fast.x, tau])
                    result = fast
                    diagnostics.torques_eliminated = True
            except SolverError:
                pass
        try:
            if result is None:
                rows, _ = dynamic_rows(terms, contacts, tasks, s.damping_gain, with_inequalities=False, loads=loads)
                relaxed = result = self._solve(context, hqp, rows, lower, upper, s.solver, warm)
            if contacts and not diagnostics.torques_eliminated and not _wrench_rows_hold(contacts, slices, result.x):
                result = None
                full, slices = dynamic_levels(terms, contacts, tasks, s.damping_gain, loads=loads)
                result = hqp.solve(full, lower, upper, 0.0, s.solver, start=inside(lower, upper), warm=warm)
        except SolverError as error:
            # Never zero torque on a standing robot if avoidable: the relaxed optimum (dynamics,
            # contact accelerations and the stack exact; friction/CoP rows possibly violated), else
            # the dynamics and contacts alone.
            diagnostics.failure = f"t = {context.get_time():.4f} s: {error}"
            if relaxed is None:
                try:
                    levels, slices = dynamic_levels(terms, contacts, [], s.damping_gain, with_inequalities=False, loads=loads)
                    relaxed = hqp.solve(levels, lower, upper, 0.0, s.solver, start=inside(lower, upper), warm=warm)
                    diagnostics.failure += "; the stack is dropped for this tick"
                except SolverError as second:
                    diagnostics.failure += f"; {second}; zero torque"
            else:
                levels, slices = dynamic_levels(terms, contacts, tasks, s.damping_gain, with_inequalities=False, loads=loads)
                diagnostics.failure += "; the contacts' wrench rows are relaxed for this tick"
            log.warning("%s: %s", self.name, diagnostics.failure)
            if relaxed is None:
                value.set_value(DynSolution(np.zeros(self.nv), np.zeros(self.na), {}, {}, np.full(len(levels), np.nan), diagnostics))
                return
            result = relaxed
        x = result.x
        if not diagnostics.torques_eliminated:  # (the fast path computed them from the same wrenches)
            world = [world_wrench(c.rows.rotation, x[sl]) for c, sl in zip(contacts, slices, strict=True)]
        local = {c.name: x[sl].copy() for c, sl in zip(contacts, slices, strict=True)}
        diagnostics.slack_norms = result.slack_norms
        if contacts and not self._warned_contacts and result.slack_norms[1] > CONTACT_SLACK:
            self._warn_contact_slack(context, contacts, float(result.slack_norms[1]))
        diagnostics.level_solvers = result.level_solvers
        diagnostics.active_bounds = result.active_bounds
        diagnostics.held_bounds = held_bounds(x, lower, upper, result.active_bounds)
        diagnostics.solve_time_s = result.solve_time_s
        wrenches = {c.name: W for c, W in zip(contacts, world, strict=True)}
        value.set_value(DynSolution(x[: self.nv].copy(), x[n - self.na :].copy(), wrenches, local, result.slack_norms, diagnostics))

    def _warn_contact_slack(self, context: Context, contacts: list[ActiveContact], slack: float) -> None:
        """Warn (once per solver) when the contacts' level is not met: the held contacts accelerate,
        because the hard bounds above them (joint accelerations, torques) leave too little, e.g. soles
        moving at the start asked to stop at once (``K_v``). The slack is in the diagnostics at every
        tick (``slack_norms[1]``); nothing else tells it."""
        reference = math.sqrt(sum(float(c.rows.acceleration @ c.rows.acceleration) for c in contacts))
        if slack > CONTACT_SLACK * max(1.0, reference):
            self._warned_contacts = True
            log.warning("%s: t = %.3f s: the contacts' zero acceleration is missed by %.3g (m/s², rad/s²): the "
                        "joint-acceleration and torque bounds leave too little, the held contacts accelerate; see "
                        "diagnostics.slack_norms[1] (warned once)", self.name, context.get_time(), slack)

    def _bounds(self, terms: DynamicsTerms, s: DynSettings, contacts: list[ActiveContact], slices: list[slice]
                ) -> tuple[np.ndarray, np.ndarray]:
        """:func:`variable_bounds` with the joint limits as acceleration bounds
        (:func:`.terms.mirrored_acceleration_bounds`, the limits stacked once) and the joints out of
        the control selection held (``q̈ = 0``, sot-core's ``controlSelec``); the free and torque
        bounds come from a read-only template per problem size (a pure cache)."""
        n = (slices[-1].stop if slices else self.nv) + self.na
        template = self._bound_templates.get(n)
        if template is None:
            free = np.full(n - self.na, np.inf)
            template = self._bound_templates[n] = (read_only(np.concatenate((-free, -self.effort))),
                                                   read_only(np.concatenate((free, self.effort))))
        return bounds(template[0], template[1], terms.q, terms.v, *self._joint_indices, *self._stacked_limits, s.horizon,
                      s.position_margin, s.control_selection, normal_force_limits(contacts, slices))

    def _actuated_rows(self, B: np.ndarray) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
        """:func:`actuated_rows` (None: ``B`` is not a selection), and the actuated and unactuated
        velocity rows (:func:`unactuated_rows`) as read-only int64 arrays, for the compiled fast
        path; kept for a read-only ``B`` (the dynamic entity's, the same array at every tick): a pure cache."""
        if self._actuation is not None and self._actuation[0] is B:
            return self._actuation[1:]
        rows = actuated_rows(B)
        if rows is None:
            compiled = _NO_INDICES, _NO_INDICES
        else:
            compiled = (read_only(rows.astype(np.int64)), read_only(np.arange(self.nv, dtype=np.int64)[unactuated_rows(self.nv, rows)]))
        if not B.flags.writeable:
            self._actuation = (B, rows, *compiled)
        return (rows, *compiled)

    def _held_guess(self, context: Context) -> tuple[list[int], list[int]]:
        """The components held at their lower and at their upper bound at the last tick's optimum."""
        guess = self.held_bound_guess(context).tolist()
        return [int(g) - 1 for g in guess if g > 0], [int(-g) - 1 for g in guess if g < 0]

    def _solve_stacked(self, context: Context, hqp: HierarchicalQP, stack: StackedLevels, lower: np.ndarray,
                       upper: np.ndarray, solver: str, warm: WarmStart | None = None) -> HqpResult:
        """:meth:`_solve` of equality levels already stacked (:func:`.reduced_levels.reduced_stack`)."""
        if solver == ACTIVE_SET:
            result = solve_stacked(stack, lower, upper, *self._held_guess(context))
            if result is not None:
                return result
        return hqp.solve(stack.levels(), lower, upper, 0.0, solver, start=inside(lower, upper), warm=warm)

    def _solve(self, context: Context, hqp: HierarchicalQP, rows: list[Rows], lower: np.ndarray, upper: np.ndarray,
               solver: str, warm: WarmStart | None = None) -> HqpResult:
        """The hierarchy through its QR path when that is clear-cut (every level an equality, the
        bounds at the optimum held as equalities and certified by their multipliers:
        :mod:`..hqp.equality_hierarchy`, the same answer), else ``hqp`` (which checks the rows).
        The QR path starts from the bounds held at the last tick (discrete state); it is not tried
        when a Drake solver is chosen."""
        if solver == ACTIVE_SET and all(lo is hi for _, lo, hi in rows):
            result = solve_equality_hierarchy([(A, b) for A, b, _ in rows], lower, upper, *self._held_guess(context))
            if result is not None:
                return result
        return hqp.solve([LevelRows(*level) for level in rows], lower, upper, 0.0, solver, start=inside(lower, upper),
                         warm=warm)

    def _calc_wrenches(self, context: Context, output) -> None:
        wrenches = self._solution.Eval(context).wrenches
        out = np.zeros(6 * self.max_contacts)
        for i, name in enumerate(self._contact_ports):
            if name in wrenches:
                w = wrenches[name]
                out[6 * i + 6 - len(w) : 6 * i + 6] = w
        output.SetFromVector(out)

    def previous_loads(self, context: Context, names: list[str]) -> np.ndarray | None:
        """The normal force (N) each named contact carried at the previous tick, or None if one of
        them was not held then."""
        loads = self._previous_loads(context, names)
        return None if loads is None else np.array(loads)

    def _previous_loads(self, context: Context, names: list[str]) -> list[float] | None:
        """:meth:`previous_loads` as Python floats."""
        record = context.get_discrete_state(self._memory).get_value()[self._loads].tolist()  # a few floats
        loads = [record[self._contact_index[name]] for name in names]
        return loads if all(math.isfinite(f) for f in loads) else None

    def _update(self, context: Context, state) -> None:
        """Record each contact's normal force and the bounds held at the optimum; start the ramp of
        a newly released contact, from the normal force it carries now."""
        s = self._settings_of(context)
        solution = self._solution.Eval(context)
        local = solution.local_wrenches
        memory = state.get_mutable_value(self._memory)  # initialized to the current state: changed in place
        ramps = self._ramps.start
        for i, name in enumerate(self._contact_ports):
            load = float(local[name][-1]) if name in local else math.nan
            memory[self._loads.start + i] = load
            r = ramps + 2 * i
            if name not in s.releasing or name not in s.contacts:
                memory[r] = memory[r + 1] = math.nan
            elif math.isnan(memory[r]):
                memory[r], memory[r + 1] = context.get_time(), 0.0 if math.isnan(load) else load
        memory[self._held] = solution.diagnostics.held_bounds
