"""``SolverDyn``'s types: its settings (held in its Context), its solution and diagnostics (the
values of its outputs), one tick's problem as read from its ports, and the error of an unknown
contact."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..compiled import read_only
from ..exceptions import NotFound
from ..hqp import ACTIVE_SET
from ..solvers.stack import StackSettings
from ..task import TaskLevel
from .formulation import HELD_BOUNDS, ActiveContact
from .terms import DynamicsTerms


class ContactNotFound(NotFound):
    """An unknown contact name given to ``SolverDyn`` (lists the solver's contacts)."""

    kind = "contact"


@dataclass
class DynSettings(StackSettings):
    """``SolverDyn``'s settings (in its Context): the stack's, the contacts being released (name →
    ramp duration, s) and the number of each one's release (name → the count of releases commanded
    so far when it was released: a contact held again and released anew starts a new ramp even if
    no tick passed in between), ``K_d`` (1/s), the joint-limit horizon (s), margin (rad) and torque
    braking, the QP solver."""

    releasing: dict[str, float] = field(default_factory=dict)  # contact name → ramp duration (s)
    release_numbers: dict[str, int] = field(default_factory=dict)  # contact name → which release it is
    releases: int = 0  # the releases commanded so far
    damping_gain: float = 10.0  # K_d of the last level (1/s)
    horizon: float = 0.05  # s, joint limits as acceleration bounds
    position_margin: float = 1e-3
    torque_braking: bool = False  # each joint's horizon stretched to what its torque brakes
    solver: str = ACTIVE_SET


_NO_VALUES, _NO_INDICES = read_only(np.zeros(0)), read_only(np.zeros(0, dtype=int))
_NO_HELD_BOUNDS = read_only(np.zeros(HELD_BOUNDS))


@dataclass
class DynDiagnostics:
    """``SolverDyn``'s ``diagnostics`` output at one tick: the levels' names and slack norms, the
    path that solved each stage, the bounds of ``x`` active at the optimum, the solve time (s), a
    failure message (empty: none), whether ``τ`` was eliminated (the fast path), and the bounds held
    at the optimum (:func:`.formulation.held_bounds`)."""

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
    """One tick's solution: ``q̈`` (nv), ``τ`` (na), each held contact's world and local wrench,
    the slack norm of each level and the diagnostics."""

    acceleration: np.ndarray
    torque: np.ndarray
    wrenches: dict[str, np.ndarray]  # world wrench (n, f) of each active contact
    local_wrenches: dict[str, np.ndarray]
    residuals: np.ndarray
    diagnostics: DynDiagnostics


@dataclass
class Problem:
    """One tick's problem, read from the ports: the dynamics terms, the held contacts and where
    their wrenches lie in ``x``, the tasks, the contacts' loads at the previous tick (N), the bounds
    on ``x`` and the levels' names."""

    terms: DynamicsTerms
    contacts: list[ActiveContact]
    tasks: list[TaskLevel]
    loads: list[float] | None
    slices: list[slice]
    lower: np.ndarray
    upper: np.ndarray
    names: list[str]
