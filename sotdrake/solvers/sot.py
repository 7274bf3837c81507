"""The ``SOT`` entity: the stack of tasks and the basic cascade solver around it.

Input ports: one per task known to the solver, named after the task, carrying its
:class:`~sotdrake.task.TaskLevel`. Only the tasks in the stack are evaluated. The stack (task names,
highest priority first), the contacts, the SVD threshold and the damping are the entity's settings,
held in the Context (see :mod:`sotdrake.entity`); ``push`` appends at the lowest priority, as in
sot-core. Contacts (``addContact``/``rmContact``, sot-dyninv) are tasks solved together as one level
above the whole stack; the last contact cannot be removed (the robot would lose its support).
``addContact(task, priority="bottom")`` is sot-dyninv's kinematic ``addContact`` instead: ``keep()``
then ``push``, the contact an ordinary task at the bottom of the stack.

Outputs: ``control`` (``v``, size nv, Drake generalized velocities) and ``residuals`` (per level,
``‖J_i v - ė_i*‖``). An empty stack gives ``v = 0``: the robot holds still.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context

from ..configuration import Layout
from ..exceptions import SolverError
from ..hqp.cascade import cascade_residuals
from ..hqp.stack_paths import CASCADE
from .kinematic import KinematicSolver
from .stack import MAX_DAMPING, MAX_SVD_THRESHOLD, StackSettings
from .velocity_scaling import scale_to_limits, velocity_scale

__all__ = ["MAX_DAMPING", "MAX_SVD_THRESHOLD", "SOT", "StackSettings"]

log = logging.getLogger("sotdrake.sot")


class _CascadeSolution:
    """The cascade's velocity, ranks and the uniform scale applied to fit the velocity limits (1: none);
    the residuals are computed when the ``residuals`` output is read (most ticks only need the
    velocity). ``tasks``: each task's name and Jacobian (what the last tick keeps)."""

    def __init__(self, velocity: np.ndarray, ranks: np.ndarray, levels: list[tuple[np.ndarray, np.ndarray]],
                 scale: float = 1.0, tasks: list[tuple[str, np.ndarray, np.ndarray | None]] | None = None):
        self.velocity, self.ranks, self._levels = velocity, ranks, levels
        self._residuals: np.ndarray | None = None
        self.scale = scale
        self.tasks = tasks or []

    @property
    def residuals(self) -> np.ndarray:
        if self._residuals is None:
            self._residuals = cascade_residuals(self._levels, self.velocity)
        return self._residuals


class SOT(KinematicSolver[StackSettings]):
    """Strict-priority kinematic solver (sot-core ``SOT``): the cascade of damped pseudo-inverses
    over the levels of its :class:`~.stack.Stack` (see the module docstring).

    Inputs: one per task (named after it, a :class:`~sotdrake.task.TaskLevel` over ``v``) and, with
    a ``layout``, ``position`` (``q``). Outputs: ``control`` (``v``, nv, rad/s and m/s),
    ``residuals`` (per level, ``‖J_i v − ė_i*‖``) and ``velocity_scale`` (the uniform scale into the
    velocity and step limits, 1 when none).
    """

    accepts_inequalities = False

    def __init__(
        self,
        name: str,
        nv: int,
        svd_threshold: float = 1e-4,
        damping: float = 0.0,
        settings: StackSettings | None = None,
        dt: float | None = None,
        layout: Layout | None = None,
    ):
        """``dt`` (the control period, s): with it, the solver corrects each level for the curvature
        of the tick (:mod:`.second_order`), its last command ``v`` and each level's ``J v`` kept in
        the Context (discrete state, updated every ``dt``). ``layout`` (of the robot's ``q``): for a
        solver that reads ``q`` on a ``position`` input."""
        KinematicSolver.__init__(self, name, nv, settings or StackSettings(), svd_threshold, damping, dt, layout)

    def _calc(self, context: Context, value: AbstractValue) -> None:
        s = self._settings_of(context)
        # The checks of every level's values run only when the solve goes wrong (to name the
        # task); the shapes and the equality of each level are checked on every tick.
        levels = self._levels(context, s, check=False)
        nv = self.nv
        for level in levels:
            J = level.jacobian
            if J.ndim != 2 or J.shape[1] != nv or level.lower.shape != (J.shape[0],) or level.upper.shape != (J.shape[0],):
                self._levels(context, s)  # raises, naming the task
            if not level.is_equality:
                self._levels(context, s)  # a NaN makes unequal bounds: named first
                raise SolverError(f"{self.name} cannot solve inequality rows: use the hierarchical QP")
        pairs = [(level.jacobian, level.reference) for level in levels]
        limit = self._velocity_limit(s)
        # With limits, the curvature corrections' own velocity too, in the same pass (see below).
        corrections = None if limit is None else [p - r for (_, r), p in zip(pairs, levels.plain, strict=False)]
        try:
            result = CASCADE.factorize(pairs, nv, s.svd_threshold, s.damping, s.control_selection, corrections)
        except (SolverError, ValueError, np.linalg.LinAlgError):
            result = None
        if result is None or not math.isfinite(result.velocity.sum() + sum(r.sum() for _, r in pairs)):
            self._levels(context, s)  # a non-finite level: raises, naming the task
            raise SolverError(f"{self.name}: the cascade gave a non-finite control at t = {context.get_time()}")
        velocity, scale = result.velocity, 1.0
        if limit is not None:
            scale = velocity_scale(velocity, limit)
            if scale < 1.0:
                # The cascade is linear in the references (for its rank decisions, which depend on
                # the Jacobians only): scale the tasks' ė* but not the curvature correction c (its
                # size is the one of the scaled motion), i.e. the same factorisation's v for
                # s·ė* - c = s·(ė* - c) - (1 - s)·c: s·v - (1 - s)·v_c, v_c the corrections' velocity
                # (solved with v), then keep within the limits.
                assert corrections is not None and result.extra_velocity is not None
                pairs = [(J, scale * r - (1.0 - scale) * c) for (J, r), c in zip(pairs, corrections, strict=False)]
                velocity, second = scale_to_limits(scale * velocity - (1.0 - scale) * result.extra_velocity, limit)
                scale *= second
                if not self._warned_scaling:
                    self._warned_scaling = True
                    log.warning("%s: t = %.3f s: the stack asks more than the velocity (or step) limits; the command is "
                                "scaled by %.3g (warned once)", self.name, context.get_time(), scale)
        value.set_value(_CascadeSolution(velocity, result.ranks, pairs, scale, levels.tasks))
