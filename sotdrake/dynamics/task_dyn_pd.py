"""``TaskDynPD`` (sot-dyninv): an acceleration-level task over any feature.

With the feature's error ``e``, Jacobian ``J = ∂e/∂v`` and ``ė_ref`` (``errordot``: the error's rate
due to a moving reference alone), the error's rate is ``ė = J v + ė_ref`` and its acceleration
``ë = J q̈ + J̇ v − s̈*`` (``s̈*`` the reference's acceleration in the error's rows). The task asks
``ë = ë* = −K_p e − K_v ė``, i.e. the rows (in ``q̈``)::

    J q̈ = −K_p e − K_v ė + ë_ref − J̇ v

with ``ë_ref`` the optional ``reference_acceleration`` input (default 0). ``J̇ v`` is the optional
``drift`` input when connected (exact, e.g. the CoM's from the dynamic entity), else the Jacobian's
finite difference over the control tick, ``(J_k − J_{k−1})/dt · v`` (as sot-dyninv's ``TaskDynPD``
does; the previous Jacobian is discrete state, and the first tick takes ``J̇ = 0``; a task built
with ``exact_drift=True`` has no such memory and no per-tick update: its ``drift`` is connected).
With the optional input ``stack`` connected (the solver's output of that name, the names of the
tasks in its stack), the Jacobian is recorded only at the ticks the task is in the stack (as
sot-dyninv, where the task records it when the solver computes it): a task waiting to be pushed
computes nothing, and the first tick after it enters takes ``J̇ = 0``. Gains
``K_p ≥ 0`` (1/s²) and ``K_v ≥ 0`` (1/s) are settings in the Context (``setGain``, ``setKp``,
``setKv``); ``setGain(Kp)`` alone takes the critical damping ``K_v = 2√K_p``.

Inputs ``feature`` (a feature's ``signals``: ``e``, ``J`` and ``ė_ref`` through one port, as the
kinematic :class:`~sotdrake.task.Task` reads them) or, when it is not connected, ``error``,
``jacobian`` and ``errordot`` (optional); ``velocity`` (v), ``drift`` (optional),
``reference_acceleration`` (optional), ``stack`` (optional). Outputs ``task`` (a :class:`~sotdrake.task.TaskLevel` over
``q̈``) and ``error_norm``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context

from ..entity import Entity
from ..exceptions import InvalidInput, StackError, check_count, check_number
from ..features.base import FeatureValue, feature_signals, optional_input, usual_input
from ..task import TaskLevel, unconnected_input_message
from .checks import MAX_DT, MAX_PD_GAIN, check_pd_gains, check_positive


@dataclass
class DynPDSettings:
    kp: float = 100.0
    kv: float = 20.0


def pd_reference(e: np.ndarray, e_dot: np.ndarray, kp: float, kv: float, reference_acceleration: np.ndarray | None,
                 drift: np.ndarray) -> np.ndarray:
    """``−K_p e − K_v ė + ë_ref − J̇ v``: the right-hand side of the task rows."""
    out = -kp * e  # then in place, in the same order: (((−K_p e) − K_v ė) − J̇ v) + ë_ref
    out -= kv * e_dot
    out -= drift
    if reference_acceleration is not None:
        out += reference_acceleration
    return out


class TaskDynPD(Entity[DynPDSettings]):
    """Acceleration task (see the module docstring).

    Inputs: ``feature`` (``e``, ``J``, ``ė_ref`` in one value) or ``error`` (``e``), ``jacobian``
    (``J``, rows × nv) and ``errordot`` (``ė_ref``, unit/s); ``velocity`` (``v``, nv); with a
    ``dimension``, ``drift`` (``J̇ v``, unit/s²) and ``reference_acceleration`` (``ë_ref``, unit/s²),
    of the error's rows or of all the feature's components, and then ``rows`` (the feature's
    ``selected_rows``: the task takes those components, so that the feature's mask may change);
    without an exact drift, ``stack`` (the solver's solved task names: the previous Jacobian is kept
    only while the task is solved). Outputs: ``task`` (a :class:`~sotdrake.task.TaskLevel` over
    ``q̈``, unit/s²) and ``error_norm`` (``‖e‖``).
    """

    is_inequality = False

    def __init__(self, name: str, nv: int, dt: float, kp: float = 100.0, kv: float | None = None,
                 dimension: int | None = None, exact_drift: bool = False):
        """``dimension``: the size of the (vector) inputs ``drift`` and ``reference_acceleration``,
        which exist only when it is given (the feature's number of selected rows, or of all its
        components with the ``rows`` input connected).
        ``exact_drift``: ``drift`` will always be connected (e.g. the CoM's ``J̇ v``), so the task
        keeps no previous Jacobian and has no per-tick update (it needs ``dimension``)."""
        Entity.__init__(self, name, DynPDSettings())
        self.nv = check_count(f"{name}: nv", nv, 1, 10**6)
        self.dt = check_positive(f"{name}: dt", dt, MAX_DT, " s")
        #: The most rows a feature may give: nv, or 6 (a pose) on a robot of fewer velocities.
        self.max_rows = max(self.nv, 6)
        if dimension is not None:
            dimension = check_count(f"{name}: dimension (the feature's rows)", dimension, 1, self.max_rows)
        if exact_drift and dimension is None:
            raise InvalidInput(f"{name}: exact_drift needs the drift input, i.e. a dimension")
        self.exact_drift = bool(exact_drift)
        self.setGain(kp, kv)
        self.feature = self.DeclareAbstractInputPort(
            "feature", AbstractValue.Make(FeatureValue(np.zeros(0), np.zeros((0, nv)), np.zeros(0))))
        self.error = self.DeclareAbstractInputPort("error", AbstractValue.Make(np.zeros(0)))
        self.jacobian = self.DeclareAbstractInputPort("jacobian", AbstractValue.Make(np.zeros((0, nv))))
        self.errordot = self.DeclareAbstractInputPort("errordot", AbstractValue.Make(np.zeros(0)))
        self.velocity = self.DeclareVectorInputPort("velocity", nv)
        self.drift = self.reference_acceleration = None
        if dimension is not None:
            self.drift = self.DeclareVectorInputPort("drift", dimension)
            self.reference_acceleration = self.DeclareVectorInputPort("reference_acceleration", dimension)
        self.rows = self.DeclareAbstractInputPort("rows", AbstractValue.Make(np.zeros(0, dtype=int)))
        # The previous Jacobian as discrete state (rows, then J row-major, up to max_rows rows): a discrete
        # update is computed from the same context as the device's and the plant's step (the physical
        # plant's outputs are not sampled), so every system of a tick sees the same J̇ (an
        # unrestricted update would be applied before them).
        self.stack = None
        if not self.exact_drift:
            self._previous = self.DeclareDiscreteState(np.zeros(1 + self.max_rows * nv))
            self.DeclarePeriodicDiscreteUpdateEvent(self.dt, 0.0, self._remember)
            self.stack = self.DeclareAbstractInputPort("stack", AbstractValue.Make(()))
        empty = TaskLevel(np.zeros((0, nv)), np.zeros(0), np.zeros(0), np.zeros(0))
        self._task = self.DeclareAbstractOutputPort("task", lambda: AbstractValue.Make(empty), self._calc)
        self.DeclareVectorOutputPort("error_norm", 1, lambda c, o: o.SetAtIndex(0, float(np.linalg.norm(self._task.Eval(c).error))))

    # --- settings ----------------------------------------------------------------------------
    def setGain(self, kp: float, kv: float | None = None, context: Context | None = None) -> None:
        """``K_p`` (1/s²) and ``K_v`` (1/s, default ``2√K_p``: critically damped), both numbers ≥ 0
        that keep the loop stable at the tick ``dt`` (:func:`.checks.check_pd_gains`)."""
        gains = self.check_gains(self.name, kp, kv, self.dt)

        def change(s: DynPDSettings) -> None:
            s.kp, s.kv = gains

        self._command(context, change)

    @staticmethod
    def check_gains(name: str, kp, kv, dt: float) -> tuple[float, float]:
        """``(K_p, K_v)`` as :meth:`setGain` takes them (``kv=None``: ``2√K_p``), checked before a
        task is built or a gain changed (:func:`.checks.check_pd_gains`)."""
        if kv is None:
            kp = check_pd_gains(name, kp, 0.0, dt)[0]  # a bad K_p is named first
            kv = 2.0 * math.sqrt(kp)
        return check_pd_gains(name, kp, kv, dt)

    def setKp(self, kp: float, context: Context | None = None) -> None:
        """``K_p`` alone (1/s²), ``K_v`` left as it is when the change applies (inside ``attime``: at
        its time, after the commands timed before it), the pair checked stable then."""
        kp = check_number(f"{self.name}: Kp", kp, 0.0, MAX_PD_GAIN, " 1/s²")

        def change(s: DynPDSettings) -> None:
            s.kp, s.kv = check_pd_gains(self.name, kp, s.kv, self.dt)

        self._command(context, change)

    def setKv(self, kv: float, context: Context | None = None) -> None:
        """``K_v`` alone (1/s), as :meth:`setKp`."""
        kv = check_number(f"{self.name}: Kv", kv, 0.0, MAX_PD_GAIN, " 1/s")

        def change(s: DynPDSettings) -> None:
            s.kp, s.kv = check_pd_gains(self.name, s.kp, kv, self.dt)

        self._command(context, change)

    # --- calc --------------------------------------------------------------------------------
    def _inputs(self, context: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """``(e, J, ė_ref)`` from ``feature``, else from ``error``, ``jacobian``, ``errordot``."""
        return feature_signals(context, self.feature, self.error, self.jacobian, self.errordot)

    def _remember(self, context: Context, state) -> None:
        if self.drift is not None and self.drift.HasValue(context):
            return  # the exact J̇ v is connected: the previous Jacobian is never read
        stack = usual_input(self.stack, context, None)
        if stack is not None and self.name not in stack:  # not in the stack: nothing recorded (J̇ = 0 when it enters)
            state.get_mutable_value(self._previous)[0] = 0.0
            return
        J = self._inputs(context)[1]
        if J.shape[0] > self.max_rows:
            raise InvalidInput(f"{self.name}: a Jacobian of {J.shape[0]} rows, more than max(nv, 6) = {self.max_rows}")
        memory = state.get_mutable_value(self._previous)  # (the state as it is: entries past J's are not read)
        memory[0] = J.shape[0]
        memory[1 : 1 + J.size] = J.ravel()

    def _previous_jacobian(self, context: Context) -> np.ndarray:
        memory = context.get_discrete_state(self._previous).get_value()
        rows = int(memory[0])
        return memory[1 : 1 + rows * self.nv].reshape(rows, self.nv)

    def _calc(self, context: Context, value: AbstractValue) -> None:
        s = self._settings_of(context)
        try:
            e, J, errordot = self._inputs(context)
        except RuntimeError as error:
            missing = unconnected_input_message(self.name, error, "MetaTaskDyn6d")
            if missing is not None:
                raise StackError(missing) from None
            raise
        v = self.velocity.Eval(context)
        e_dot = J @ v
        if errordot is not None:
            e_dot += self._sized("errordot", errordot, e, context)
        if self.exact_drift:
            drift = self.drift.Eval(context)  # type: ignore[union-attr]
        else:
            drift = optional_input(self.drift, context, None) if self.drift is not None else None
        if drift is not None:
            drift = self._sized("drift", drift, e, context)
        else:
            previous = self._previous_jacobian(context)
            drift = (J - previous) @ v / self.dt if previous.shape == J.shape and previous.shape[0] else np.zeros_like(e)
        reference = self._sized("reference_acceleration", self.reference_acceleration.Eval(context), e, context) \
            if self.reference_acceleration is not None and self.reference_acceleration.HasValue(context) else None
        rhs = pd_reference(e, e_dot, s.kp, s.kv, reference, drift)
        value.set_value(TaskLevel(J, rhs, rhs, e))

    def _sized(self, what: str, value: np.ndarray, e: np.ndarray, context: Context) -> np.ndarray:
        """``value`` as the error's rows: as it is, or its components the ``rows`` input selects."""
        if type(value) is np.ndarray and value.shape == e.shape and value.dtype == float:
            return value  # as the ports give it (the usual case)
        value = np.asarray(value, dtype=float).reshape(-1)
        if value.shape != e.shape and self.rows.HasValue(context):
            rows = self.rows.Eval(context)
            if rows.size == e.size and rows.size and value.size > rows[-1]:
                value = value[rows]
        if value.shape != e.shape:
            raise InvalidInput(f"{self.name}: {what} has {value.size} rows, the error has {e.size}")
        return value
