"""The seed's hand-made sequencer: ``attime(T, command, description)``.

``attime(1.0, lambda: sot.push(taskRH.task.name), "push RH")`` (or the seed's tuple form
``attime(T, (lambda: ..., "description"))``) runs ``command`` once at build time *in recording
mode*: every entity command it issues without a context is recorded instead of applied. Each entity
touched gets a timed event at ``T`` that replays its commands on the state of the context being
simulated, so the sequence is part of the diagram: a reset or cloned context replays it exactly.
Call it before creating the simulator's context: a context that already exists runs a command
scheduled later only if its time has not passed ``T`` yet (warned); the schedule is the diagram's,
so every context and clone not yet at ``T`` runs it, whenever it was made.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Callable
from typing import NamedTuple

from .entity import Entity, _recorders
from .exceptions import InvalidInput, SotError, SotWarning, check_number

#: Latest time an attime command may be scheduled at (s): a year of simulated time.
MAX_TIME = 3.2e7

log = logging.getLogger("sotdrake.sequencer")


class TimedCommand(NamedTuple):
    time: float
    description: str
    entities: tuple[str, ...]


def attime(time: float, command: Callable[[], object] | tuple, description: str = "") -> TimedCommand:
    """Schedule ``command`` (entity commands without a context) at simulated time ``time`` (s).
    ``command`` may also be ``(command, description)``. Each entity the command changes applies its
    part at ``time`` on its own: a part refused then (see :mod:`sotdrake.entity`) leaves that
    entity unchanged, not the others."""
    if isinstance(command, tuple):
        if len(command) != 2 or not isinstance(command[1], str):
            raise InvalidInput(f"attime: a command is a callable or (callable, description), got a tuple of {len(command)}")
        command, description = command
    check_number("attime: the time (s)", time, 0.0, MAX_TIME)
    if not callable(command):
        raise InvalidInput(f"attime: the command must be callable (a lambda issuing entity commands), got {command!r:.100}")
    recorded: list = []
    _recorders.append(recorded)
    try:
        command()
    finally:
        _recorders.pop()
    if not recorded:
        raise SotError(f"attime({time}, {description!r}): the command issued no entity command")
    by_entity: dict[Entity, list] = {}
    for entity, change in recorded:
        by_entity.setdefault(entity, []).append(change)
    late = [entity.name for entity in by_entity if len(entity._in_contexts)]
    if late:
        warnings.warn(f"attime({time}, {description!r}): a context of {late} already exists; one whose time is already "
                      "past T never runs this command, and every context (its clones too, made before or after) "
                      "whose time has not passed T runs it: the diagram changed, not a context (schedule before "
                      "creating the simulator's context, or use the live runner's attime, which refuses a past "
                      "time)", SotWarning, stacklevel=2)
    for entity, changes in by_entity.items():
        if description:
            changes = [*changes, lambda _s, d=description, t=time: log.info("t = %.3f s: %s", t, d)]
        entity._declare_timed_change(float(time), changes)
    return TimedCommand(float(time), description, tuple(e.name for e in by_entity))
