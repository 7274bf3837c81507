"""The SoT habits ``entity.displaySignals()`` and ``signal.value``, for Drake diagrams.

``entities(diagram)`` lists the systems; ``displaySignals(entity, context)`` prints every input and
output port of an entity with its value at the context's time (inputs that are not connected say
so), ``displayAll(diagram, context)`` every entity's; ``signal(entity, name, context)`` returns one
port's value (output, else input).
"""

from __future__ import annotations

import copy
from collections.abc import Iterator
from typing import TextIO

import numpy as np
from pydrake.systems.framework import Context, Diagram, System

from .entity import own_context
from .exceptions import NotFound, SotError, check_name, check_type


def entities(diagram: Diagram) -> list[str]:
    """Names of the diagram's systems, in the order they were added."""
    check_type("entities: diagram", diagram, Diagram, "a built Diagram (builder.Build())")
    return [system.get_name() for system in diagram.GetSystems()]


def all_systems(diagram: Diagram) -> Iterator[System]:
    """Every system of ``diagram`` and, depth first, of its subdiagrams."""
    for system in diagram.GetSystems():
        yield system
        if isinstance(system, Diagram):
            yield from all_systems(system)


def entity(diagram: Diagram, name: str) -> System:
    """The system named ``name`` in ``diagram`` (sot-core's entity by name); :class:`NotFound` lists the names."""
    check_type("entity: diagram", diagram, Diagram, "a built Diagram (builder.Build())")
    check_name("entity: name", name)
    for system in diagram.GetSystems():
        if system.get_name() == name:
            return system
    raise NotFound(name, entities(diagram))


def signal(system: System, name: str, context: Context):
    """Value of the output (else input) port ``name`` of ``system`` in ``context`` (root or own), as
    a copy (sot-core's ``signal.value``): the value held by the context's cache is overwritten when
    the simulation goes on, the copy keeps the value at the time it was read."""
    check_type("signal: system", system, System, "an entity (a Drake system)")
    check_name("signal: name", name)
    own = own_context(system, context)
    if system.HasOutputPort(name):
        return _snapshot(_value(system.GetOutputPort(name).EvalAbstract(own)))
    if system.HasInputPort(name):
        port = system.GetInputPort(name)
        if not port.HasValue(own):
            raise NotFound(f"{name} (not connected)", [])
        return _snapshot(_value(port.EvalAbstract(own)))
    ports = [system.get_input_port(i).get_name() for i in range(system.num_input_ports())]
    ports += [system.get_output_port(i).get_name() for i in range(system.num_output_ports())]
    raise NotFound(name, ports)


def _value(abstract):
    value = abstract.get_value()
    return value.get_value() if hasattr(value, "get_value") and not isinstance(value, np.ndarray) else value


def _snapshot(value):
    """A copy of ``value`` that does not refer into the context's cache (a deep copy; a value that
    cannot be deep-copied is copied one level)."""
    try:
        return copy.deepcopy(value)
    except Exception:  # (a bound type without deep copy)
        return copy.copy(value)


def _format(value, width: int = 100) -> str:
    with np.printoptions(precision=4, suppress=True, linewidth=width):
        text = repr(value) if not isinstance(value, np.ndarray) else np.array2string(value)
    text = " ".join(text.split())
    return text if len(text) <= width else text[: width - 1] + "…"


def signals_report(system: System, context: Context) -> str:
    """The entity's signals and their values at ``context``'s time, as text."""
    check_type("signals_report: system", system, System, "an entity (a Drake system)")
    own = own_context(system, context)
    lines = [f"{system.get_name()} ({type(system).__name__}) at t = {own.get_time():.4f} s"]
    for kind, count, get in (("in ", system.num_input_ports(), system.get_input_port),
                             ("out", system.num_output_ports(), system.get_output_port)):
        for i in range(count):
            port = get(i)
            if kind == "in " and not port.HasValue(own):
                text = "(not connected)"
            else:
                try:
                    text = _format(_value(port.EvalAbstract(own)))
                except (RuntimeError, SotError) as error:  # an upstream input not connected, a signal this robot has not
                    text = f"(cannot evaluate: {(str(error).splitlines() or [type(error).__name__])[0]})"
            lines.append(f"  {kind} {port.get_name():24s} {text}")
    return "\n".join(lines)


def displaySignals(system: System, context: Context, file: TextIO | None = None) -> None:
    """Print the entity's signals and their values at ``context``'s time (sot-core's
    ``entity.displaySignals()``). It returns nothing, so the prompt shows the table once; the text
    itself is :func:`signals_report`."""
    check_type("displaySignals: system", system, System, "an entity (a Drake system)")
    print(signals_report(system, context), file=file)


def displayAll(diagram: Diagram, context: Context, file: TextIO | None = None) -> None:
    """``displaySignals`` of every entity of the diagram."""
    check_type("displayAll: diagram", diagram, Diagram, "a built Diagram (builder.Build())")
    for system in diagram.GetSystems():
        displaySignals(system, context, file)
