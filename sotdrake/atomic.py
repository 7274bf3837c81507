"""Builders that add several systems either add them all or leave the builder as it was, whether
a system is one of a builder's, and whether it is already in a built diagram (its contexts would not
have a port added now)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from pydrake.systems.framework import DiagramBuilder, System


def in_builder(builder: DiagramBuilder, system: System) -> bool:
    """Whether ``system`` (this very object) is one of ``builder``'s systems."""
    return any(other is system for other in builder.GetSystems())


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
