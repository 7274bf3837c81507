"""Checks of a built diagram's stacks before it runs: :func:`check_stack`.

A task that cannot be evaluated (no gain, no feature) would otherwise fail inside the first tick
with Drake's ``InputPort::Eval(): required InputPort[3] (controlGain) … is not connected``; an
inequality task without bounds would constrain nothing, silently. :func:`check_stack` looks at
every solver of the diagram (``SOT``, ``SolverKine``, ``SolverDyn``), at each task of its stack
(and each member of a weighted level) and its contacts, and raises :class:`~sotdrake.exceptions.StackError` naming the task and what it
lacks, or warns (:class:`~sotdrake.exceptions.SotWarning`) for an inequality task without bounds.
:func:`sotdrake.simulate` calls it before running; a task evaluated in a ``Simulator`` of your own
raises the same :class:`StackError` at its first evaluation.
"""

from __future__ import annotations

from pydrake.systems.framework import Context, Diagram, System

from .device import Device
from .entity import probing
from .exceptions import StackError, check_type
from .solvers.stack import StackSolver
from .task import TaskInequality, _TaskBase
from .task_weight import TaskWeight


def _systems_by_name(diagram: Diagram) -> dict[str, System]:
    return {system.get_name(): system for system in diagram.GetSystems()}


def check_stack(diagram: Diagram, context: Context | None = None) -> None:
    """Check every solver's stack and contacts in ``context`` (the root context; default: a new
    default context, made without counting as a running one). Raises :class:`StackError` for a
    task without gain or feature; warns once for an inequality task without bounds."""
    check_type("check_stack: diagram", diagram, Diagram, "a built Diagram (builder.Build())")
    if context is None:
        with probing():
            context = diagram.CreateDefaultContext()
    systems = _systems_by_name(diagram)
    connected = {(system.get_name(), int(index)) for system, index in diagram.connection_map()}
    for device in diagram.GetSystems():  # (nothing on a device's control: Drake's error in the first tick)
        if isinstance(device, Device) and (device.get_name(), int(device.control.get_index())) not in connected:
            raise StackError(f"{device.get_name()}: its control input is not connected: add a solver (add_sot(robot))")
    for solver in systems.values():
        if not isinstance(solver, StackSolver):
            continue
        settings = solver.settings(context)
        for name in [*settings.contacts, *settings.tasks]:
            task = systems.get(name)
            if not isinstance(task, (_TaskBase, TaskWeight)):
                continue
            missing = task.missing_inputs(context)
            if missing is not None:
                raise StackError(f"{solver.name}: {missing}")
            for each in task.member_tasks() if isinstance(task, TaskWeight) else [task]:
                if isinstance(each, TaskInequality):
                    each.warn_if_unbounded(context)
