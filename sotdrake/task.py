"""SoT tasks: the reference behaviour of one feature, as rows ``lower ≤ J v ≤ upper`` for a solver.

* ``Task``: ``ė* = -λ(e)·e - ė_ref``, an equality (``lower = upper = ė*``); ``ė_ref`` is the
  feature's ``errordot`` (the error's rate due to a moving reference: velocity feed-forward), zero
  when the optional ``errordot`` input is not connected.
* ``TaskPD``: ``ė* = -λ e - β ė - ė_ref``, where ``ė`` is the error's rate over the last tick
  (``(e_k - e_{k-1})/dt``, held in the Context); ``setBeta(β)``.
* ``TaskInequality`` (sot-dyninv): bounds ``e_min ≤ e ≤ e_max`` on the feature's error, as velocity
  rows ``λ(e_min - e) ≤ J v ≤ λ(e_max - e)``: the error may approach a bound at most exponentially
  with rate λ, and is driven back at that rate when outside. Only solvers that take inequalities
  (``SolverKine``) accept it; the basic ``SOT`` refuses it at ``push``.

Inputs ``feature`` (a feature's ``signals``: ``e``, ``J = ∂e/∂v`` and ``ė_ref`` together, as
sot-core's ``task.add(feature)``) and ``controlGain`` (``λ``, 1/s). When ``feature`` is not
connected, the task reads ``error`` (``e``), ``jacobian`` (``J``) and, optional, ``errordot``
instead (any source of rows). Outputs ``task``, a :class:`TaskLevel` for the solvers, and
``error_norm`` (``‖e‖``, for tracing).
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafContext, LeafSystem

from .entity import Entity
from .exceptions import InvalidInput, SotWarning, StackError, all_numbers, check_count, check_finite, check_name, finite_number
from .features.base import FeatureValue, feature_signals
from .gain_checks import error_norm
from .progress import ProgressWatch
from .ranges import MAX_TARGET_POSITION

#: The derivative gain β of a TaskPD (dimensionless: ė* = -λ e - β ė) is below this (exclusive):
#: with ``β ≥ 1`` the error's two-step recursion diverges whatever λ (see :class:`TaskPD`).
MAX_BETA = 1.0


class TaskLevel(NamedTuple):
    """What a solver needs of a task: rows ``lower ≤ J v ≤ upper`` (equal for an equality task).
    ``row_keys``: for a level whose rows are not the same from one tick to the next (the collision
    pairs in range), which row is which (one integer per row, the same for the same row at every
    tick); None for a task's fixed rows."""

    jacobian: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    error: np.ndarray
    row_keys: np.ndarray | None = None

    @property
    def is_equality(self) -> bool:
        return self.lower is self.upper or np.array_equal(self.lower, self.upper)

    @property
    def reference(self) -> np.ndarray:
        """``ė*`` of an equality task."""
        return self.lower


_UNCONNECTED = re.compile(r"required InputPort\[\d+\] \((.+?)\) of System (\S+) \(([\w.]+)\) is not connected")


def unconnected_port(error: BaseException) -> tuple[str, str, str] | None:
    """``(port, system, kind)`` when ``error`` is Drake's "required InputPort[i] (port) of System
    ::…::system (kind) is not connected": the input's name, its system's name and the system's
    class; None for another error."""
    match = _UNCONNECTED.search(str(error))
    if match is None:
        return None
    port, path, kind = match.groups()
    return port, path.rsplit("::", 1)[-1], kind


def unconnected_input_message(task_name: str, error: RuntimeError, meta_task: str = "MetaTaskKine6d") -> str | None:
    """A sentence naming what is missing when ``error`` is Drake's "required InputPort … is not
    connected" (:func:`unconnected_port`), raised while task ``task_name`` was evaluated
    (``meta_task``: the kind of meta task that would have connected it); None for another error."""
    found = unconnected_port(error)
    if found is None:
        return None
    port, system, kind = found
    if system == task_name and port == "controlGain":
        return (f"task {task_name!r} has no gain: connect a gain's 'gain' output to its 'controlGain' input, e.g. "
                f"builder.Connect(gain.GetOutputPort('gain'), task.GetInputPort('controlGain')) with "
                "gain = GainAdaptive(...), or build it with a meta task (MetaTaskKine6d …), which does")
    if system == task_name:
        return (f"task {task_name!r} has no feature: connect a feature's 'signals' output to its 'feature' input "
                f"(or its 'error' and 'jacobian' inputs), or build it with a meta task ({meta_task} …), which does")
    return (f"task {task_name!r} cannot be evaluated: the input {port!r} of {system!r} ({kind.rsplit('.', 1)[-1]}) "
            "is not connected (a meta task connects its feature's inputs)")


def _empty(nv: int) -> TaskLevel:
    return TaskLevel(np.zeros((0, nv)), np.zeros(0), np.zeros(0), np.zeros(0))


class _TaskBase(LeafSystem):
    """Ports shared by the task kinds; ``_rows(context, e, gain)`` gives ``(lower, upper)``.

    Inputs: ``feature`` (a :class:`~.features.base.FeatureValue`: ``e``, ``J``, ``ė_ref`` in one
    value) or, the seed's way, ``error`` (``e``, the feature's unit), ``jacobian`` (``J = ∂e/∂v``,
    rows × nv) and ``errordot`` (``ė_ref``, unit/s); ``controlGain`` (``λ``, 1/s, from a gain).
    Outputs: ``task`` (a :class:`TaskLevel` over ``v``: ``lower ≤ J v ≤ upper``, unit/s) and
    ``error_norm`` (``‖e‖``, the feature's unit).
    """

    is_inequality = False

    def _rows(self, context: Context, e: np.ndarray, gain: float) -> tuple[np.ndarray, np.ndarray]:
        """``(lower, upper)`` of the rows ``lower ≤ J v ≤ upper`` (the same array for an equality)."""
        raise NotImplementedError

    def _declare_ports(self, nv: int) -> None:
        self.nv = nv = check_count(f"{self.get_name()}: nv (the velocities)", nv)
        self._progress = ProgressWatch(self.get_name())  # logging only (sotdrake.progress)
        self.feature = self.DeclareAbstractInputPort(
            "feature", AbstractValue.Make(FeatureValue(np.zeros(0), np.zeros((0, nv)), np.zeros(0))))
        self.error = self.DeclareAbstractInputPort("error", AbstractValue.Make(np.zeros(0)))
        self.jacobian = self.DeclareAbstractInputPort("jacobian", AbstractValue.Make(np.zeros((0, nv))))
        self.controlGain = self.DeclareVectorInputPort("controlGain", 1)
        self.errordot = self.DeclareAbstractInputPort("errordot", AbstractValue.Make(np.zeros(0)))
        self._task_output = self.DeclareAbstractOutputPort("task", lambda: AbstractValue.Make(_empty(nv)), self._calc)
        self.DeclareVectorOutputPort(
            "error_norm", 1, lambda c, o: o.SetAtIndex(0, error_norm(self._task_output.Eval(c).error)),
            prerequisites_of_calc={self.cache_entry_ticket(self._task_output.cache_entry().cache_index())},
        )

    @property
    def name(self) -> str:
        return self.get_name()

    def _inputs(self, context: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """``(e, J, ė_ref)`` from ``feature``, else from ``error``, ``jacobian``, ``errordot``."""
        return feature_signals(context, self.feature, self.error, self.jacobian, self.errordot)

    def missing_inputs(self, context: Context) -> str | None:
        """What keeps this task from being evaluated in ``context`` (its own or the root's): a
        sentence naming the task and the unconnected input (its gain, its feature, an input of its
        feature), or None when it can be evaluated."""
        own = context if isinstance(context, LeafContext) else self.GetMyContextFromRoot(context)
        try:
            self._inputs(own)
            self.controlGain.Eval(own)
        except RuntimeError as error:
            return unconnected_input_message(self.name, error)
        except Exception:  # another problem: the run reports it itself, from its own state
            return None
        return None

    def _calc(self, context: Context, value: AbstractValue) -> None:
        try:
            e, J, e_dot = self._inputs(context)
            gain = self.controlGain.Eval(context)[0]
        except RuntimeError as error:
            missing = unconnected_input_message(self.name, error)
            if missing is not None:
                raise StackError(missing) from None
            raise
        lower, upper = self._rows(context, e, gain)
        if lower is upper:  # an equality task: is its error still falling?
            self._progress.observe(context.get_time(), e)
        if e_dot is not None and np.count_nonzero(e_dot):
            if e_dot.shape != e.shape:
                raise InvalidInput(f"{self.name}: errordot has {e_dot.size} rows, error has {e.size}")
            equality = upper is lower  # keep an equality one array (TaskLevel.is_equality)
            lower = lower - e_dot
            upper = lower if equality else upper - e_dot
        value.set_value(TaskLevel(J, lower, upper, e))


class Task(_TaskBase):
    """Equality task ``J v = -λ(e)·e``.

    Ports: those of every task (``feature`` or ``error`` / ``jacobian`` / ``errordot``,
    ``controlGain``; ``task``, ``error_norm``): see :class:`_TaskBase`.
    """

    def __init__(self, name: str, nv: int):
        check_name("Task name", name)
        LeafSystem.__init__(self)
        self.set_name(name)
        self._declare_ports(nv)

    def _rows(self, context, e, gain):
        reference = -gain * e
        return reference, reference


@dataclass
class PDSettings:
    beta: float = 0.0


class TaskPD(_TaskBase, Entity[PDSettings]):
    """``ė* = -λ e - β ė - ė_ref`` with ``ė = (e_k - e_{k-1})/dt`` (zero on the first tick and when
    the error changes size).

    Realised exactly, the error follows ``e_{k+1} = (1 − λ dt − β) e_k + β e_{k−1}``, whose roots lie
    inside the unit circle (Jury's test) if and only if ``λ dt > 0`` and ``0 ≤ β < 1 − λ dt / 2``:
    ``setBeta`` refuses ``β ≥ 1`` (unstable for every λ), and the task warns once when the gain it
    reads makes ``β ≥ 1 − λ dt / 2`` (the error would oscillate and grow instead of converging).

    The previous error is discrete state ``[rows, e_{k-1}, 0…]`` (rows -1 before the first tick),
    updated every ``dt`` together with the device: Drake computes every discrete update of a tick
    from the same context, so the command of tick k sees ``e_{k-1}``. (An unrestricted update would
    run before the device's update and hand it ``e_k``, i.e. ``ė = 0``.) ``max_rows`` (default nv, an
    integer in [1, :data:`~sotdrake.exceptions.MAX_COUNT`]) is the largest error the task keeps; a
    larger one is refused.

    Ports: those of every task (``feature`` or ``error`` / ``jacobian`` / ``errordot``,
    ``controlGain``; ``task``, ``error_norm``): see :class:`_TaskBase`.
    """

    def __init__(self, name: str, nv: int, dt: float, max_rows: int | None = None):
        Entity.__init__(self, name, PDSettings())
        if not (finite_number(dt) and dt > 0):
            raise InvalidInput(f"{name}: dt must be a number > 0 (s), got {dt!r}")
        self.dt = float(dt)
        self._warned_beta = False
        rows = None if max_rows is None else check_count(f"{name}: max_rows", max_rows)
        self._declare_ports(nv)
        self.max_rows: int = self.nv if rows is None else rows
        self._previous = self.DeclareDiscreteState(np.concatenate([[-1.0], np.zeros(self.max_rows)]))
        self.DeclarePeriodicDiscreteUpdateEvent(self.dt, 0.0, self._remember)

    def setBeta(self, beta: float, context: Context | None = None) -> None:
        if not finite_number(beta) or not 0 <= beta < MAX_BETA:
            raise InvalidInput(f"{self.name}.setBeta: β must be a number in [0, {MAX_BETA:g}) (β ≥ 1 makes the error "
                               f"diverge), got {beta!r}")
        self._command(context, lambda s: setattr(s, "beta", float(beta)))

    def _remember(self, context: Context, discrete_state) -> None:
        e = self._inputs(context)[0]
        if e.size > self.max_rows:
            raise InvalidInput(f"{self.name}: the error has {e.size} rows, more than the {self.max_rows} this TaskPD keeps "
                               "(its max_rows)")
        kept = discrete_state.get_mutable_value(self._previous)
        kept[0], kept[1 : 1 + e.size] = e.size, e

    def _rows(self, context, e, gain):
        kept = context.get_discrete_state(self._previous).get_value()
        rate = (e - kept[1 : 1 + e.size]) / self.dt if kept[0] == e.size else np.zeros_like(e)
        beta = self._settings_of(context).beta
        if beta > 0.0 and not self._warned_beta:
            bound = 1.0 - 0.5 * float(np.max(gain)) * self.dt  # (stable below it: see the class docstring)
            if beta >= bound:
                self._warned_beta = True  # (logging only)
                warnings.warn(f"{self.name}: β = {beta:g} ≥ 1 − λ dt / 2 = {bound:g}: the error oscillates and grows "
                              "instead of converging; lower β or λ (warned once)", SotWarning, stacklevel=2)
        reference = -gain * e - beta * rate
        return reference, reference


@dataclass
class InequalityBounds:
    lower: np.ndarray = field(default_factory=lambda: np.zeros(0))
    upper: np.ndarray = field(default_factory=lambda: np.zeros(0))


class TaskInequality(_TaskBase, Entity[InequalityBounds]):
    """Inequality task ``e_min ≤ e ≤ e_max`` (see the module docstring). Bounds are settings:
    ``setBounds(lower, upper)``, one per selected row of the feature, ±inf for a free side. Until
    they are set, every row is free (and the task warns once when it is evaluated in a stack).

    Ports: those of every task (``feature`` or ``error`` / ``jacobian`` / ``errordot``,
    ``controlGain``; ``task``: the rows ``e_min ≤ e + J v dt ≤ e_max`` as bounds on ``J v``,
    unit/s; ``error_norm``): see :class:`_TaskBase`.
    """

    is_inequality = True

    def __init__(self, name: str, nv: int):
        Entity.__init__(self, name, InequalityBounds())
        self._warned_unbounded = False  # logging only
        self._declare_ports(nv)

    def setBounds(self, lower, upper, context: Context | None = None) -> None:
        try:
            if not (all_numbers(lower) and all_numbers(upper)):
                raise TypeError("not numbers")
            lower = np.asarray(lower, dtype=float).reshape(-1)
            upper = np.asarray(upper, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise InvalidInput(f"{self.name}.setBounds: lower and upper must be numbers, got {lower!r:.100}, {upper!r:.100}") from None
        for what, bound in (("lower", lower), ("upper", upper)):
            finite = bound[np.isfinite(bound)]
            if bound.shape != upper.shape or bound.size == 0 or np.any(np.isnan(bound)) or np.any(np.abs(finite) > MAX_TARGET_POSITION):
                raise InvalidInput(
                    f"{self.name}: {what} bound must be as many numbers as the other, each ±inf or in "
                    f"[-{MAX_TARGET_POSITION:g}, {MAX_TARGET_POSITION:g}] (no NaN)")
        if np.any(lower > upper) or np.any(np.isposinf(lower)) or np.any(np.isneginf(upper)):
            raise InvalidInput(f"{self.name}: lower bound above upper bound, or a side no error meets (lower = +inf, "
                               f"upper = -inf): {lower}, {upper}")
        rows = self._feature_rows(context)
        if rows is not None and rows != lower.size:
            raise InvalidInput(f"{self.name}.setBounds: {lower.size} bounds, the feature's error has {rows} rows now "
                               "(one bound per selected row)")

        def set_bounds(s: InequalityBounds) -> None:
            s.lower, s.upper = lower.copy(), upper.copy()

        self._command(context, set_bounds)

    def _feature_rows(self, context: Context | None) -> int | None:
        """The rows of the feature's error in ``context`` (None without a context, or when the
        inputs cannot be evaluated there: the tick then says what is missing)."""
        if context is None:
            return None
        try:
            return int(self._inputs(self.own_context(context))[0].size)
        except Exception:  # (an unconnected or failing input: not this command's business)
            return None

    def unbounded(self, context: Context | None = None) -> bool:
        """True while no bounds are set (in ``context``, else in the defaults): the task is inert."""
        return self.settings(context).lower.size == 0

    def warn_if_unbounded(self, context: Context | None = None) -> None:
        """Warn (once per task, :class:`~sotdrake.exceptions.SotWarning`) if the task has no bounds."""
        if self.unbounded(context) and not self._warned_unbounded:
            self._warned_unbounded = True
            warnings.warn(f"{self.name}: an inequality task in the stack without bounds (setBounds was never called): "
                          f"every row is free, it constrains nothing; call {self.name}.setBounds(lower, upper)",
                          SotWarning, stacklevel=2)

    def _rows(self, context, e, gain):
        s = self._settings_of(context)
        if s.lower.size == 0:  # no bounds yet: every row free
            if not self._warned_unbounded:
                self.warn_if_unbounded(context)
            return np.full(e.shape, -np.inf), np.full(e.shape, np.inf)
        if e.shape != s.lower.shape:
            raise InvalidInput(f"{self.name}: error has {e.size} rows, bounds have {s.lower.size}")
        check_finite(f"{self.name}.controlGain", gain)
        with np.errstate(invalid="ignore"):
            lower, upper = gain * (s.lower - e), gain * (s.upper - e)
        if gain == 0.0:  # (0·∞: a free side stays free)
            lower[np.isneginf(s.lower)], upper[np.isposinf(s.upper)] = -np.inf, np.inf
        return lower, upper
