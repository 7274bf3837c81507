"""``SolverDyn`` (sot-dyninv): the stack solved for ``x = (q̈, w_1 … w_k, τ)`` in strict priority.

A system around :mod:`.formulation` (the unknowns, the levels and the bounds: the dynamics, the
contacts, the user's stack of :class:`~sotdrake.task.TaskLevel` over ``q̈``, the damping and the
wrench regularization): each tick it reads its ports, forms the problem, solves it and writes the
outputs. Hard bounds on ``x`` are never violated.

How it is solved (``τ`` eliminated first when ``B`` is a selection, then the full problem, then
the rescues) is :mod:`.dyn_solve`; the hierarchical QP then takes the minimum-norm ``x`` of the
optimal set (smallest torques and wrenches among the equivalent ones).

``rmContact(name, duration)`` releases a contact smoothly: from the first tick after the command,
its normal force's upper bound ramps linearly from the normal force it carried then down to 0 over
``duration`` seconds, and its lower bound from ``f_min`` down to 0 (so the force never jumps: with
the lower bound dropped to 0 at once, a sole held at 30 N went to 0 N in one tick); the contact is
removed once the ramp ends, so the foot lifts off carrying no force. The ramps are discrete state
(:mod:`.contact_memory`); the contact set is a setting.

Ports: see :class:`SolverDyn`.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, InputPort, ValueProducer

from ..compiled import read_only
from ..configuration import Layout
from ..exceptions import InvalidInput, SolverError, StackError, check_count, check_flag, check_name, check_number
from ..hqp import ACTIVE_SET, HqpResult, check_solver
from ..hqp.warm import WarmStart, WarmStarts
from ..robots import RobotModel
from ..solvers.stack import Stack, StackSolver
from ..task import TaskLevel
from .checks import (
    MAX_CONTACTS,
    MAX_DT,
    MAX_HORIZON,
    MAX_POSITION_MARGIN,
    MAX_RATE_GAIN,
    MIN_HORIZON,
    check_positive,
    usable_task_rows,
)
from .contact import Contact6d, world_wrench
from .contact_memory import ContactMemory
from .dyn_contacts import DynContacts
from .dyn_solve import DynamicSolve
from .dyn_types import DynDiagnostics, DynSettings, DynSolution, Problem
from .formulation import (
    CONTACT_SLACK,
    DYNAMICS_SLACK,
    ActiveContact,
    held_bounds,
    normal_force_limits,
    wrench_slices,
)
from .reduced_levels import bounds
from .terms import DynamicsTerms, stacked_limits, torque_braking

log = logging.getLogger("sotdrake.solver_dyn")


def _reference_braking(model: RobotModel, effort: np.ndarray) -> np.ndarray:
    """:func:`.terms.torque_braking` at the model's reference posture (``half_sitting``): one value a
    joint, so that the joint limits' bounds stay consistent from tick to tick."""
    plant = model.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, model.half_sitting)
    return torque_braking(plant.CalcMassMatrix(context), plant.MakeActuationMatrix(), effort)


class SolverDyn(StackSolver[DynSettings]):
    """Inverse-dynamics solver with contacts (see the module docstring): its :class:`~..solvers.stack.Stack`
    of tasks over ``q̈``, its contacts, and the formulation of :mod:`.formulation`.

    Inputs: ``dynamics`` (:class:`.terms.DynamicsTerms`: ``M``, ``h``, ``B``, ``q``, ``v``), one per
    contact (``contact<name>``, :class:`.contact.ContactRows`) and one per task (a
    :class:`~sotdrake.task.TaskLevel` over ``q̈``). Outputs: ``control`` (``q̈``, nv, rad/s² and
    m/s²), ``torque`` (``τ``, na, N·m and N, actuator order), ``wrenches`` (each declared
    contact's world wrench ``(n, f)`` about its origin, N·m and N, 6 per contact, zero when not
    held), ``residuals`` (slack norm per level), ``velocity_scale`` (always 1), ``diagnostics``
    (:class:`DynDiagnostics`) and ``stack`` (the names of the tasks solved).
    """

    accepts_inequalities = True

    def __init__(self, name: str, model: RobotModel, dt: float, max_contacts: int = 2, damping_gain: float = 10.0,
                 solver: str = ACTIVE_SET, effort_scale: float = 1.0):
        """``effort_scale`` in (0, 1]: the torque bounds are this fraction of the model's effort
        limits (a derated robot; 1: the limits of the URDF)."""
        check_name(f"SolverDyn({name!r:.40})", name)
        if not isinstance(model, RobotModel):
            raise InvalidInput(f"{name}: model must be a RobotModel (load_robot, load_talos), got {model!r:.60}")
        effort_scale = check_positive(f"{name}: effort_scale", effort_scale, 1.0)  # any real number type, not a bool
        dt = check_positive(f"{name}: dt", dt, MAX_DT, " s")
        max_contacts = check_count(f"{name}: max_contacts", max_contacts, 1, MAX_CONTACTS)
        StackSolver.__init__(self, name, DynSettings())
        self.nv = model.nv
        self.stack_of_tasks = Stack(self, model.nv, self.accepts_inequalities)
        self._declare_solution_and_common_outputs()
        self._warned_contacts = False  # logging only: results never depend on it
        self._warned_dynamics = False  # logging only
        self.dt, self.model = dt, model
        self.layout = self._layout = Layout.of(model.plant)
        limits = model.joint_limits()
        self._limits = (limits["position_lower"], limits["position_upper"], limits["velocity_lower"], limits["velocity_upper"])
        iq, iv = self._layout.joints_q, self._layout.joints_v
        # the joints' rows and limits, indexed and stacked once (_bounds: both sides in one evaluation)
        self._joint_indices = (read_only(iq.astype(np.int64)), read_only(iv.astype(np.int64)))
        self._stacked_limits = stacked_limits(self._limits[0][iq], self._limits[1][iq], self._limits[2][iv], self._limits[3][iv])
        self.effort = limits["effort"] * float(effort_scale)  # |τ| bounds (N·m, N)
        self.effort_scale = float(effort_scale)
        self.braking = read_only(_reference_braking(model, self.effort))  # nv: what each joint's torque brakes
        self._joint_braking = (read_only(np.full(len(iv), np.inf)), read_only(np.ascontiguousarray(self.braking[iv])))
        self.na = len(self.effort)
        self.max_contacts = max_contacts
        self.setDampingGain(damping_gain)
        self.setSolver(solver)
        self.contact_set = DynContacts(self, self.nv, max_contacts)  # the contacts' inputs and commands
        self._contact_ports, self._contact_index = self.contact_set.ports, self.contact_set.index
        self._solve = DynamicSolve(self.nv, self.na, self.effort)  # the solve, with its caches of solvers
        # Their warm starts (which path answers), in the Context, one per problem (see
        # sotdrake.hqp.warm): a cloned or reset Context replays a run bit for bit. The solves update
        # them in place (left out of the solution's prerequisites: nothing is recomputed for them).
        self._warm_index = self.DeclareAbstractState(AbstractValue.Make(WarmStarts()))
        self._bound_templates: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # see _bounds
        self.dynamics = self.DeclareAbstractInputPort("dynamics", AbstractValue.Make(
            DynamicsTerms(np.eye(self.nv), np.zeros(self.nv), np.zeros(self.nv), np.zeros((self.nv, self.na)),
                          np.zeros(model.nq), np.zeros(self.nv), 1.0)))
        self._memory = ContactMemory(self, max_contacts, self.dt, self._update)  # loads, held bounds, ramps
        self.DeclareVectorOutputPort("torque", self.na, lambda c, o: o.SetFromVector(self._solution.Eval(c).torque))
        # The names of the tasks in the stack: a TaskDynPD records its Jacobian only while in it.
        self.DeclareAbstractOutputPort("stack", lambda: AbstractValue.Make(()),
                                       lambda c, o: o.set_value(self.solved_tasks(self._settings_of(c))),
                                       prerequisites_of_calc={self.abstract_state_ticket(self._settings_index)})
        self.DeclareVectorOutputPort("wrenches", 6 * max_contacts, self._calc_wrenches)
        self.DeclareAbstractOutputPort("diagnostics", lambda: AbstractValue.Make(DynDiagnostics()),
                                       lambda c, o: o.set_value(self._solution.Eval(c).diagnostics))

    def _declare_solution_and_common_outputs(self) -> None:
        """The ``solution`` cache entry (its sources: the inputs, the settings, the discrete state:
        the contact ramps) and the ports ``control`` (``q̈``), ``residuals`` and ``velocity_scale``
        (always 1: the solver scales nothing)."""
        empty = DynSolution(np.zeros(self.nv), np.zeros(0), {}, {}, np.zeros(0), DynDiagnostics())
        self._solution = self.DeclareCacheEntry(
            "solution",
            ValueProducer(allocate=lambda: AbstractValue.Make(empty), calc=self._calc),
            prerequisites_of_calc={self.all_input_ports_ticket(), self.all_parameters_ticket(), self.xc_ticket(),
                                   self.abstract_state_ticket(self._settings_index), self.xd_ticket()},
        )
        self.DeclareVectorOutputPort("control", self.nv, lambda c, o: o.SetFromVector(self._solution.Eval(c).acceleration))
        self.DeclareAbstractOutputPort(
            "residuals", lambda: AbstractValue.Make(np.zeros(0)), lambda c, o: o.set_value(self._solution.Eval(c).residuals)
        )
        self.DeclareVectorOutputPort("velocity_scale", 1, lambda c, o: o.SetAtIndex(0, 1.0))

    # --- wiring ------------------------------------------------------------------------------
    def declare_contact_input(self, contact: Contact6d) -> InputPort:
        """The input port of ``contact`` (its ``contact`` output goes there)."""
        return self.contact_set.declare_input(contact)

    @property
    def known_contacts(self) -> list[str]:
        """The declared contacts, in declaration order."""
        return list(self._contact_ports)

    # --- commands ----------------------------------------------------------------------------
    def _dyn_command(self, context: Context | None, change: Callable[[DynSettings], None]) -> None:
        self._command(context, change)

    def addContact(self, contact, context: Context | None = None, priority: str = "top") -> None:
        """Hold ``contact`` (a name or a :class:`Contact6d`); a contact being released is held again.
        A dynamic contact is a constraint of every level: ``priority`` is ``"top"`` only."""
        self.contact_set.addContact(contact, context, priority)

    def rmContact(self, contact, duration: float = 0.3, context: Context | None = None) -> None:
        """Release ``contact``: its normal force ramps to 0 over ``duration`` s (≥ 0), then it is
        removed. Removing the last held contact is refused. (sot-dyninv's ``rmContact``, with the
        ramp's duration: not the kinematic SOT's signature.)"""
        self.contact_set.rmContact(contact, duration, context)

    def setDampingGain(self, gain: float, context: Context | None = None) -> None:
        """``K_d`` in [0, :data:`.checks.MAX_RATE_GAIN`] (1/s) of the last level ``q̈ = −K_d v``."""
        value = check_number(f"{self.name}: damping gain K_d", gain, 0.0, MAX_RATE_GAIN, " 1/s")
        if value * self.dt >= 1.0:  # (v ← (1 − K_d dt) v: from 1 on, v changes sign every tick)
            raise InvalidInput(f"{self.name}: damping gain K_d = {value:g} 1/s at dt = {self.dt:g} s: K_d dt must be < 1, "
                               f"got {value * self.dt:g}")
        self._dyn_command(context, lambda s: setattr(s, "damping_gain", value))

    def setSolver(self, solver: str, context: Context | None = None) -> None:
        check_solver(solver)
        self._dyn_command(context, lambda s: setattr(s, "solver", solver))

    def setJointLimitHorizon(self, horizon: float, margin: float = 1e-3, context: Context | None = None) -> None:
        """Joint limits as acceleration bounds over ``horizon`` s (in [:data:`.checks.MIN_HORIZON`,
        :data:`.checks.MAX_HORIZON`]), ``margin`` rad (in [0, :data:`.checks.MAX_POSITION_MARGIN`])."""
        values = (check_number(f"{self.name}: joint-limit horizon", horizon, MIN_HORIZON, MAX_HORIZON, " s"),
                  check_number(f"{self.name}: joint-limit margin", margin, 0.0, MAX_POSITION_MARGIN, " rad"))

        def change(s: DynSettings) -> None:
            s.horizon, s.position_margin = values

        self._dyn_command(context, change)

    def setTorqueBraking(self, on: bool, context: Context | None = None) -> None:
        """Whether each joint's limits count on no more braking than its torque gives
        (:attr:`braking`: half its effort on its own inertia at the reference posture, rad/s²): where
        that is below ``v_max/T`` the joint's horizon stretches to ``T_j = v_max/A_j`` and its
        stopping bound brakes at ``A_j`` (:func:`.terms.acceleration_bounds`), so a weak joint (a
        shoulder, the torso) slows down early enough for its own torque to stop it at its limit,
        rather than leaving the rest of the body to absorb the difference. Off by default."""
        value = check_flag(f"{self.name}: setTorqueBraking", on)
        self._dyn_command(context, lambda s: setattr(s, "torque_braking", value))

    # The kinematic solvers' settings, which SolverDyn has no use for: refused rather than ignored.
    def setThreshold(self, svd_threshold: float, context: Context | None = None) -> None:
        """Refused: the levels are solved exactly, there is no SVD threshold."""
        raise StackError(f"{self.name} is a SolverDyn: its levels are solved exactly (hierarchical QP), it has no SVD "
                         "threshold (setThreshold is the kinematic SOT's)")

    def setDamping(self, damping: float, context: Context | None = None) -> None:
        """Refused: the remaining motion is damped by the last level (:meth:`setDampingGain`)."""
        raise StackError(f"{self.name} is a SolverDyn: it has no damped least squares (setDamping is the kinematic "
                         "solvers'); the remaining motion is damped by its last level: setDampingGain")

    def setVelocityLimit(self, limit, context: Context | None = None) -> None:
        """Refused: the solver commands accelerations and torques."""
        raise StackError(f"{self.name} is a SolverDyn: it commands accelerations and torques, not velocities (the joints' "
                         "velocity limits enter its acceleration bounds: setJointLimitHorizon)")

    # --- solve -------------------------------------------------------------------------------
    def held_bound_guess(self, context: Context) -> np.ndarray:
        """The bounds held at the last tick's optimum (:func:`held_bounds`), as recorded in ``context``
        (the solver's own)."""
        return self._memory.held_bound_guess(context)

    def _active_contacts(self, context: Context, s: DynSettings) -> list[ActiveContact]:
        """The held contacts, and the released ones whose ramp has not ended (with their bound)."""
        return self.contact_set.active(context, s, self._memory)

    def held_contacts(self, context: Context) -> list[str]:
        """The contacts the solver uses at the context's time (being released ones included)."""
        own = self.own_context(context)
        return [c.name for c in self._active_contacts(own, self._settings_of(own))]

    def contacts(self, context: Context | None = None) -> list[str]:
        """The contacts as commanded, less those whose release ramp has ended (``rmContact``: then
        the contact is removed). Without a context (the default one), the commanded contacts."""
        if context is None:
            return self.stack_of_tasks.contacts()
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
            entries, lower, upper = J.ravel(), level.lower, level.upper
            if not (math.isfinite(entries @ entries) and math.isfinite(lower @ lower)
                    and (upper is lower or math.isfinite(upper @ upper))) and not usable_task_rows(J, lower, upper):
                raise SolverError(f"task {name}: non-finite jacobian or reference at t = {context.get_time()} (a NaN, or "
                                  "an infinite value that is not the open side of an inequality)")
            tasks.append(level)
        return tasks

    def _problem(self, context: Context, s: DynSettings) -> Problem:
        """Read the ports: the dynamics terms, the held contacts (their ramps), the tasks, the
        loads of the previous tick, and the bounds on ``x`` (:func:`.formulation.variable_bounds`)."""
        try:
            terms = self.dynamics.Eval(context)
            contacts = self._active_contacts(context, s)
        except RuntimeError as error:
            self.contact_set.raise_if_unconnected(error)
            raise
        tasks = self._tasks(context, s)
        loads = self._previous_loads(context, [c.name for c in contacts])
        slices = wrench_slices(self.nv, contacts)
        lower, upper = self._bounds(terms, s, contacts, slices)
        names = ["dynamics"] + (["contacts"] if contacts else []) + list(s.tasks) + ["damping"]
        return Problem(terms, contacts, tasks, loads, slices, lower, upper, names)

    def _calc(self, context: Context, value: AbstractValue) -> None:
        """Read the ports → the formulation (:mod:`.formulation`) → solve (:mod:`.dyn_solve`) → the solution."""
        s = self._settings_of(context)
        p = self._problem(context, s)
        diagnostics = DynDiagnostics(levels=p.names)
        result, world, count = self._solve.solve(p, s, lambda problem, n: self._warm(context, problem, n),
                                                 self._held_guess(context), diagnostics, context.get_time(), self.name)
        if result is None:
            value.set_value(DynSolution(np.zeros(self.nv), np.zeros(self.na), {}, {}, np.full(count, np.nan), diagnostics))
            return
        value.set_value(self._solution_of(context, p, result, world, diagnostics))

    def _solution_of(self, context: Context, p: Problem, result: HqpResult, world: list[np.ndarray] | None,
                     diagnostics: DynDiagnostics) -> DynSolution:
        """The outputs of the optimum ``result.x``: ``q̈``, ``τ``, each contact's world and local
        wrench (``world``: already computed by the fast path), the slack norms and diagnostics."""
        x, contacts, slices, lower, upper = result.x, p.contacts, p.slices, p.lower, p.upper
        n = len(lower)
        if world is None:  # (the fast path computed them from the same wrenches)
            world = [world_wrench(c.rows.rotation, x[sl]) for c, sl in zip(contacts, slices, strict=True)]
        local = {c.name: x[sl].copy() for c, sl in zip(contacts, slices, strict=True)}
        diagnostics.slack_norms = result.slack_norms
        if contacts and not self._warned_contacts and len(result.slack_norms) > 1 and result.slack_norms[1] > CONTACT_SLACK:
            self._warn_contact_slack(context, contacts, float(result.slack_norms[1]))
        if not self._warned_dynamics and result.slack_norms[0] > DYNAMICS_SLACK:
            self._warn_dynamics_slack(context, p.terms, float(result.slack_norms[0]))
        diagnostics.level_solvers = result.level_solvers
        diagnostics.active_bounds = result.active_bounds
        diagnostics.held_bounds = held_bounds(x, lower, upper, result.active_bounds)
        diagnostics.solve_time_s = result.solve_time_s
        wrenches = {c.name: W for c, W in zip(contacts, world, strict=True)}
        return DynSolution(x[: self.nv].copy(), x[n - self.na :].copy(), wrenches, local, result.slack_norms, diagnostics)

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

    def _warn_dynamics_slack(self, context: Context, terms: DynamicsTerms, slack: float) -> None:
        """Warn (once per solver) when the dynamics is not met (relative to ``max(1, ‖h‖)``): the
        torque limits cannot give the joint accelerations the hard bounds require, so ``τ`` does not
        produce ``q̈``. The slack is in the diagnostics at every tick (``slack_norms[0]``)."""
        if slack > DYNAMICS_SLACK * max(1.0, float(np.linalg.norm(terms.h))):
            self._warned_dynamics = True
            log.warning("%s: t = %.3f s: the dynamics is missed by %.3g (N·m, N): the torque limits cannot give the "
                        "joint accelerations the joint-limit and selection bounds require (a joint too fast towards its "
                        "limit for the effort left), so τ does not produce q̈; see diagnostics.slack_norms[0] (warned "
                        "once)", self.name, context.get_time(), slack)

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
                      s.position_margin, self.dt, self._joint_braking[s.torque_braking], s.control_selection,
                      normal_force_limits(contacts, slices))

    def _held_guess(self, context: Context) -> tuple[list[int], list[int]]:
        """The components held at their lower and at their upper bound at the last tick's optimum."""
        guess = self.held_bound_guess(context).tolist()
        return [int(g) - 1 for g in guess if g > 0], [int(-g) - 1 for g in guess if g < 0]

    def _warm(self, context: Context, problem: str, n: int) -> WarmStart:
        """The warm start of the ``problem`` ("full" or "reduced") of ``n`` variables, kept in the
        Context's abstract state."""
        return context.get_abstract_state(self._warm_index).get_value().of((problem, n), n)

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
        them was not held then. ``names``: a list of this solver's declared contacts; a name it does
        not know is a :class:`~.dyn_types.ContactNotFound` listing those it knows."""
        loads = self._previous_loads(self.own_context(context), self.contact_set.names_of("previous_loads", names))
        return None if loads is None else np.array(loads)

    def _previous_loads(self, context: Context, names: list[str]) -> list[float] | None:
        """:meth:`previous_loads` as Python floats."""
        return self._memory.previous_loads(context, [self._contact_index[name] for name in names])

    def _update(self, context: Context, state) -> None:
        """Record each contact's normal force and the bounds held at the optimum; start the ramp of
        a newly released contact, from the normal force it carries now."""
        s = self._settings_of(context)
        solution = self._solution.Eval(context)
        local = solution.local_wrenches
        loads = [float(local[name][-1]) if name in local else math.nan for name in self._contact_ports]
        releases = [s.release_numbers.get(name) if name in s.contacts else None for name in self._contact_ports]
        self._memory.record(state, context.get_time(), loads, releases, solution.diagnostics.held_bounds)
