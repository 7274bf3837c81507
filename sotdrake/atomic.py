"""Builders that add several systems either add them all or leave the builder as it was, whether
names are free in a builder, whether a system is one of a builder's, and whether it is already in a
built diagram (its contexts would not have a port added now); whether a port may be logged or
published (a vector output port of a system of the builder)."""

from __future__ import annotations

from collections.abc import Collection, Iterator, Sequence
from contextlib import contextmanager

from pydrake.systems.framework import DiagramBuilder, OutputPort, PortDataType, System

from .exceptions import InvalidInput, SotError


def in_builder(builder: DiagramBuilder, system: System) -> bool:
    """Whether ``system`` (this very object) is one of ``builder``'s systems."""
    return any(other is system for other in builder.GetSystems())


def check_new_names(builder: DiagramBuilder, names: Sequence[str], taken: Collection[str] = (), what: str = "") -> None:
    """:class:`SotError` if ``builder`` is built, :class:`InvalidInput` if one of ``names`` is
    ``taken`` (e.g. the entities a robot added) or the name of a system of ``builder``: what adding
    an entity checks, for a caller that adds several and must refuse before adding any. ``what``:
    the caller, named first in the messages."""
    prefix = f"{what}: " if what else ""
    if builder.already_built():
        raise SotError(f"{prefix}cannot add {names[0]!r}: the diagram is already built "
                       "(create tasks, contacts and entities before builder.Build())")
    existing = set(taken) | {system.get_name() for system in builder.GetSystems()}
    for name in names:
        if name in existing:
            raise InvalidInput(f"{prefix}an entity named {name!r} already exists: give another name")


def in_built_diagram(system: System) -> bool:
    """Whether ``system`` is in a diagram (one is only made by ``builder.Build()``)."""
    return system.GetSystemPathname() != "::" + system.get_name()


@contextmanager
def all_or_nothing(builder: DiagramBuilder) -> Iterator[DiagramBuilder]:
    """``with all_or_nothing(builder): ...``: if the block raises (a refused argument found once
    some systems are in), the systems it added are removed with their connections and exported
    ports (``DiagramBuilder.RemoveSystem``) before the error goes on: the builder is as before."""
    before = {id(system) for system in builder.GetSystems()}
    try:
        yield builder
    except BaseException:
        for system in reversed(builder.GetSystems()):
            if id(system) not in before:
                builder.RemoveSystem(system)
        raise


def check_vector_port(what: str, builder: DiagramBuilder, port: object) -> OutputPort:
    """``port`` if it is a vector-valued output port of a system added to ``builder``, else
    :class:`InvalidInput` starting with ``what`` (checked before anything is added: Drake would
    refuse the connection only after its system was)."""
    need = f"{what}: it needs a vector output port of a system of this builder"
    if not isinstance(port, OutputPort):
        raise InvalidInput(f"{need}, got {type(port).__name__} {port!r:.60}")
    system = port.get_system()
    where = f"port {port.get_name()!r} of {system.get_name()!r}"
    if port.get_data_type() != PortDataType.kVectorValued:
        raise InvalidInput(f"{need}; {where} is abstract-valued (not a vector)")
    if not in_builder(builder, system):
        raise InvalidInput(f"{need}; {where} belongs to another builder")
    return port
