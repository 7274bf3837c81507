"""What a live command may call: an explicit allow-list per kind of entity, over the public API.

A :class:`Vocabulary` is built once from a diagram and its handles (the object ``build_diagram``
returns). Its targets are looked up by name in plain dictionaries; no attribute of any Python
object is ever reached by a name coming from a command:

* every system of the diagram, under its own name (``sot``, ``gainrh``, ``featurerh``,
  ``featurerh_ref``, ``taskrh``, ``device`` …), with the methods of its kind (table below) plus the
  read-only ``displaySignals()`` and ``signal('port')``;
* every field of the handles that is a solver or an entity, under the field's name (``sot``);
* every meta task of the handles under its field name (``taskRH``, ``taskCom``, ``contactLF``) with
  ``keep()``, ``gotoNd(position, selec, gain)`` and ``selec(mask)``, and its parts as
  ``taskRH.gain``, ``taskRH.feature``, ``taskRH.featureDes``, ``taskRH.task``;
* the functions ``gotoNd(task, position, selec, gain)``, ``displaySignals(entity)``,
  ``signal(entity, 'port')``, ``entities()``, ``stack()``, ``attime(T, command)``, ``time()`` and
  ``help()``, plus those the live runner adds (``status()``, ``stop()``).

| kind | methods |
| --- | --- |
| ``SOT``, ``SolverKine`` (the stack) | ``push``, ``pop``, ``remove`` (``rm``), ``up``, ``down``, ``clear``, ``stack`` |
| ``SOT``, ``SolverKine`` (contacts, settings) | ``addContact``, ``rmContact``, ``contacts``, ``setDamping``; ``SOT``: ``setThreshold`` |
| ``GainAdaptive`` | ``setConstant``, ``set(λ0, λ∞, slope)``, ``setByPoint(λ0, λ∞, e_ref, p)``, ``coefficients`` |
| ``GainHyperbolic`` | ``setConstant``, ``set(λ0, λ∞, tanAt0, decal0)``, ``coefficients`` |
| features | ``selec(mask)``; ``Feature6d`` also ``frame('desired' \\| 'current')`` |
| ``Feature6dDesired`` | ``setPosition(p)``, ``setVelocity(v)`` |
| ``FeatureGenericDesired`` | ``setReference(s)``, ``setVelocity(v)`` |
| ``TaskInequality`` / ``TaskPD`` | ``setBounds(lower, upper)`` / ``setBeta(β)`` |
| ``TaskWeight`` | ``setWeight(member, w)``, ``weights`` |
| ``SolverKine`` (acceleration limits) | ``setAccelerationLimit(a_max)`` (one number for every joint) |

:meth:`Vocabulary.prepare` turns a parsed :class:`~.grammar.Command` into a :class:`Prepared`
command: target and method found, every argument checked against its declared kind (number,
numbers, vector, text, task, entity …). Nothing touches a context until the prepared command is
called with one, at a tick boundary; the API then applies it on a copy of the settings and stores
it only on success, so a rejected command changes nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pydrake.systems.framework import Context, Diagram, System

from .. import introspection
from ..exceptions import CommandRejected, InvalidInput, NotFound, SotError
from ..features import Feature, Feature6d, Feature6dDesired, FeatureGenericDesired
from ..gains import GainAdaptive, GainHyperbolic
from ..meta_task_base import MetaTask
from ..meta_tasks import MetaTaskKine6d, MetaTaskKineCom, gotoNd
from ..sequencer import MAX_TIME
from ..solvers import SolverKine
from ..solvers.stack import StackSolver
from ..task import TaskInequality, TaskPD
from ..task_weight import TaskWeight
from .arguments import REQUIRED, Method, Param, Prepared, describe, number, vector
from .grammar import Command, EntityRef


class Vocabulary:
    """The allow-list of one diagram: targets (name → methods) and the entities names refer to."""

    def __init__(self, diagram: Diagram, handles: object = None):
        self.diagram = diagram
        self._methods: dict[str, dict[str, Method]] = {"": {}}
        self._objects: dict[str, object] = {}
        self._solver: StackSolver | None = None
        self._pending_attime: Callable[[float, Prepared], str] | None = None
        for system in diagram.GetSystems():
            self._add_system(system.get_name(), system)
        for name, value in _fields(handles):
            if isinstance(value, MetaTask):
                self._add_meta_task(name, value)
            elif isinstance(value, System) and value.get_name() in self._objects and name not in self._methods:
                self._add_system(name, value)
        self._add_functions()

    # --- construction ----------------------------------------------------------------------
    def add_function(self, name: str, params: tuple[Param, ...], apply: Callable[..., Any], doc: str = "",
                     context_only: bool = False, query: bool = False) -> None:
        """Offer ``name(...)`` (e.g. the runner's ``status()``); ``apply(context, *values)``;
        ``context_only``: it reads and changes that context only (no other effect); ``query``: it
        only answers a question."""
        self._methods[""][name] = Method(params, apply, doc, context_only, query)

    def set_scheduler(self, schedule: Callable[[float, Prepared], str]) -> None:
        """Where ``attime(T, command)`` hands its prepared command (the live runner)."""
        self._pending_attime = schedule

    def _add_system(self, name: str, system: System) -> None:
        methods: dict[str, Method] = {
            "displaySignals": Method((), lambda c, s=system: introspection.signals_report(s, c),
                                     "the entity's signals and their values"),
            "signal": Method((Param("port", "text"),), lambda c, p, s=system: introspection.signal(s, p, c),
                             "one port's value"),
        }
        if isinstance(system, StackSolver):
            self._solver = self._solver or system
            methods.update(_solver_methods(system))
        if isinstance(system, (GainAdaptive, GainHyperbolic)):
            methods["setConstant"] = Method((Param("gain", "number"),), lambda c, g, s=system: s.setConstant(g, c))
            methods["coefficients"] = Method((), lambda c, s=system: repr(s.settings(c).coefficients),
                                             "the gain's coefficients (a, b, c[, d])")
        if isinstance(system, GainAdaptive):
            methods["set"] = Method(tuple(Param(n, "number") for n in ("gain0", "gain_inf", "slope")),
                                    lambda c, *v, s=system: s.set(*v, context=c))
            methods["setByPoint"] = Method(tuple(Param(n, "number") for n in ("gain0", "gain_inf", "error_ref", "fraction")),
                                           lambda c, *v, s=system: s.setByPoint(*v, context=c))
        if isinstance(system, GainHyperbolic):
            methods["set"] = Method(tuple(Param(n, "number") for n in ("gain0", "gain_inf", "tan_at0", "decal0")),
                                    lambda c, *v, s=system: s.set(*v, context=c))
        if isinstance(system, Feature):
            methods["selec"] = Method((Param("mask", "text"),), lambda c, m, s=system: s.selec(m, c))
        if isinstance(system, Feature6d):
            methods["frame"] = Method((Param("which", "text"),), lambda c, w, s=system: s.frame(w, c))
        if isinstance(system, Feature6dDesired):
            methods["setPosition"] = Method((Param("position", "vector"),), lambda c, p, s=system: s.setPosition(p, c))
            methods["setVelocity"] = Method((Param("velocity", "vector"),), lambda c, v, s=system: s.setVelocity(v, c))
        if isinstance(system, FeatureGenericDesired):
            methods["setReference"] = Method((Param("value", "vector"),), lambda c, v, s=system: s.setReference(v, c))
            methods["setVelocity"] = Method((Param("velocity", "vector"),), lambda c, v, s=system: s.setVelocity(v, c))
        if isinstance(system, TaskInequality):
            methods["setBounds"] = Method((Param("lower", "vector"), Param("upper", "vector")),
                                          lambda c, lo, up, s=system: s.setBounds(lo, up, c))
        if isinstance(system, TaskPD):
            methods["setBeta"] = Method((Param("beta", "number"),), lambda c, b, s=system: s.setBeta(b, c))
        if isinstance(system, TaskWeight):
            methods["setWeight"] = Method((Param("member", "text"), Param("weight", "number")),
                                          lambda c, m, w, s=system: s.setWeight(m, w, c))
            methods["weights"] = Method((), lambda c, s=system: repr(s.weights(c)), "each member's weight")
        if isinstance(system, SolverKine):
            methods["setAccelerationLimit"] = Method((Param("a_max", "number"),),
                                                     lambda c, a, s=system: s.setAccelerationLimit(a, c))
        self._methods[name] = methods
        self._objects[name] = system

    def _add_meta_task(self, name: str, meta: MetaTask) -> None:
        methods = {
            "selec": Method((Param("mask", "text"),), lambda c, m: meta.feature.selec(m, c)),
        }
        keep = getattr(meta, "keep", None)  # the meta tasks with a desired value of their own
        if callable(keep):
            methods["keep"] = Method((), lambda c: keep(c), "desired value ← current value")
        if isinstance(meta, (MetaTaskKine6d, MetaTaskKineCom)):
            methods["gotoNd"] = Method(_GOTO_PARAMS[1:], lambda c, position, selec, gain: gotoNd(meta, position, selec, gain, context=c))
        self._methods[name] = methods
        self._objects[name] = meta
        for part in ("gain", "feature", "featureDes", "task"):
            system = getattr(meta, part, None)  # fixed names from this list, never from a command
            if isinstance(system, System) and system.get_name() in self._methods:
                self._methods[f"{name}.{part}"] = self._methods[system.get_name()]
                self._objects[f"{name}.{part}"] = system

    def _add_functions(self) -> None:
        def add(name: str, params: tuple[Param, ...], apply: Callable[..., Any], doc: str = "", query: bool = True) -> None:
            self.add_function(name, params, apply, doc, context_only=True, query=query)

        add("gotoNd", _GOTO_PARAMS, lambda c, meta, position, selec, gain: gotoNd(meta, position, selec, gain, context=c),
            "drive a task to a position (1, 3 or 4 gain numbers)", query=False)
        add("displaySignals", (Param("entity", "entity"),), lambda c, e: introspection.signals_report(e, c))
        add("signal", (Param("entity", "entity"), Param("port", "text")), lambda c, e, p: introspection.signal(e, p, c))
        add("entities", (), lambda c: ", ".join(introspection.entities(self.diagram)), "the diagram's systems")
        if self._solver is not None:
            solver = self._solver
            add("stack", (), lambda c: repr(solver.stack(c)), f"{solver.name}'s stack, highest priority first")
        add("attime", (Param("time", "time"), Param("command", "command")), self._attime,
            "apply a command when the simulated time reaches T (s)", query=False)
        add("time", (), lambda c: f"{c.get_time():.4f}", "the simulated time (s)")
        add("help", (), lambda c: self.help(), "this list")

    def _attime(self, context: Context, time: float, prepared: Prepared) -> str:
        if self._pending_attime is None:
            raise CommandRejected("attime: no scheduler in this run")
        if time < context.get_time():
            raise CommandRejected(f"attime: T = {time} s is in the past (t = {context.get_time():.4f} s)")
        if time > MAX_TIME:
            raise CommandRejected(f"attime: T = {time} s is beyond the latest time a command may wait for ({MAX_TIME:g} s)")
        if prepared.method.query:
            raise CommandRejected(f"attime: {prepared} only answers a question; at T its answer would go nowhere")
        if prepared.method.context_only:  # its values and names checked now, on a copy of the run's context
            try:  # (what depends on the stack at T, e.g. a push, is checked at T; the names never change)
                prepared(context.Clone())
            except CommandRejected:
                raise
            except (InvalidInput, NotFound) as error:
                raise CommandRejected(f"attime: {prepared}: {error}") from None
            except SotError:
                pass
        return self._pending_attime(time, prepared)

    # --- use -------------------------------------------------------------------------------
    @property
    def targets(self) -> list[str]:
        return [name for name in self._methods if name]

    def help(self) -> str:
        lines = [m.signature(name) for name, m in self._methods[""].items()]
        for target, methods in self._methods.items():
            if target:
                lines.append(f"{target}: {', '.join(methods)}")
        return "\n".join(lines)

    def prepare(self, command: Command) -> Prepared:
        """Check ``command`` against the allow-list and convert its arguments; no context needed."""
        if command.target not in self._methods:
            raise NotFound(command.target, self.targets)
        methods = self._methods[command.target]
        if command.method not in methods:
            what = f"method of {command.target}" if command.target else "function"
            raise CommandRejected(
                f"{command.callee}: not an allowed {what}; allowed: {', '.join(sorted(methods))}"
            )
        method = methods[command.method]
        callee = command.callee
        params = method.params
        if len(command.args) > len(params):
            raise CommandRejected(f"{callee} takes at most {len(params)} arguments: {method.signature(callee)}")
        given: dict[str, Any] = {p.name: a for p, a in zip(params, command.args, strict=False)}
        names = [p.name for p in params]
        for key, value in command.kwargs:
            if key not in names:
                raise CommandRejected(f"{callee}: no argument {key!r}: {method.signature(callee)}")
            if key in given:
                raise CommandRejected(f"{callee}: argument {key!r} given twice")
            given[key] = value
        values = []
        for p in params:
            if p.name not in given:
                if p.default is REQUIRED:
                    raise CommandRejected(f"{callee}: missing argument {p.name!r}: {method.signature(callee)}")
                values.append(p.default)
                continue
            value = given[p.name]
            if value is None and p.default is None:
                values.append(None)
                continue
            values.append(self._convert(value, p, callee))
        return Prepared(command, method, tuple(values))

    def _convert(self, value, param: Param, callee: str):
        what = f"{callee}: argument {param.name!r}"
        kind = param.kind
        try:
            if kind == "number":
                return number(value, what)
            if kind == "time":
                time = number(value, what)
                if time < 0:
                    raise CommandRejected(f"{what}: a time ≥ 0 (s), got {time}")
                return time
            if kind == "numbers":
                if isinstance(value, tuple):
                    return tuple(number(x, what) for x in value)
                return number(value, what)
            if kind == "vector":
                return vector(value, what)
            if kind == "text":
                if not isinstance(value, str):
                    raise CommandRejected(f"{what}: expected a string, got {describe(value)}")
                return value
            if kind == "task":
                if isinstance(value, str):
                    return value
                if isinstance(value, EntityRef) and value.name in self._objects:
                    task = self._objects[value.name]
                    task = getattr(task, "task", task) if isinstance(task, MetaTask) else task
                    return task.get_name() if isinstance(task, System) else value.name
                raise CommandRejected(f"{what}: expected a task name such as 'taskrh' or a task, got {describe(value)}")
            if kind == "meta":
                if isinstance(value, EntityRef) and isinstance(self._objects.get(value.name), MetaTask):
                    return self._objects[value.name]
                metas = [n for n, o in self._objects.items() if isinstance(o, MetaTask)]
                raise CommandRejected(f"{what}: expected a meta task ({', '.join(metas)}), got {describe(value)}")
            if kind == "entity":
                name = value.name if isinstance(value, EntityRef) else value
                if isinstance(name, str) and isinstance(self._objects.get(name), System):
                    return self._objects[name]
                raise CommandRejected(f"{what}: expected an entity such as sot, got {describe(value)}")
            if kind == "command":
                if not isinstance(value, Command):
                    raise CommandRejected(f"{what}: expected a command such as sot.push('taskrh'), got {describe(value)}")
                if value.target == "" and value.method == "attime":
                    raise CommandRejected(f"{what}: attime cannot be nested")
                return self.prepare(value)
        except OverflowError:
            raise CommandRejected(f"{what}: number out of range") from None
        raise CommandRejected(f"{what}: unknown kind {kind!r}")  # pragma: no cover - a table typo


_GOTO_PARAMS = (Param("task", "meta"), Param("position", "vector"), Param("selec", "text", None),
                Param("gain", "numbers", None))


def _solver_methods(solver: Any) -> dict[str, Method]:
    task = (Param("task", "task"),)
    return {
        "push": Method(task, lambda c, n: solver.push(n, c), "append at the lowest priority"),
        "pop": Method((), lambda c: solver.pop(c), "remove the lowest-priority task"),
        "remove": Method(task, lambda c, n: solver.remove(n, c)),
        "rm": Method(task, lambda c, n: solver.remove(n, c), "remove (sot-dyninv's name)"),
        "up": Method(task, lambda c, n: solver.up(n, c)),
        "down": Method(task, lambda c, n: solver.down(n, c)),
        "clear": Method((), lambda c: solver.clear(c), "empty the stack (contacts stay)"),
        "addContact": Method(task, lambda c, n: solver.addContact(n, c)),
        "rmContact": Method(task, lambda c, n: solver.rmContact(n, c)),
        "stack": Method((), lambda c: repr(solver.stack(c)), query=True),
        "contacts": Method((), lambda c: repr(solver.contacts(c)), query=True),
        "setThreshold": Method((Param("svd_threshold", "number"),), lambda c, x: solver.setThreshold(x, c)),
        "setDamping": Method((Param("damping", "number"),), lambda c, x: solver.setDamping(x, c)),
    }


def _fields(handles: object) -> list[tuple[str, object]]:
    """The public fields of the handles object (a dataclass or any object with ``__dict__``)."""
    if handles is None:
        return []
    fields = getattr(handles, "__dataclass_fields__", None)
    names = list(fields) if fields is not None else list(getattr(handles, "__dict__", {}))
    return [(n, getattr(handles, n)) for n in names if not n.startswith("_") and n.isidentifier()]
