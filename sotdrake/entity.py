"""Base class of the SoT entities whose settings change at run time.

An entity keeps its run-time settings (stack order, reference, gain coefficients, selection …) in
one abstract state of its Drake ``Context``, never in Python attributes, so a simulation is
reproducible, resettable and clonable. A command (``sot.push``, ``gain.setConstant`` …) changes
them in one of three places:

* ``context=`` the root diagram context (or the entity's own): that context only, e.g. between
  ``Simulator.AdvanceTo`` calls;
* no context, at build time: the entity's *defaults*, which every context created afterwards
  starts from (contexts already created are not touched: once a context of the entity exists, the
  first such command warns, :class:`~sotdrake.exceptions.SotWarning`, that the running context
  is not changed and how to change it);
* no context, inside :func:`sotdrake.sequencer.attime`: the command is recorded and replayed by a
  timed event of this entity.

A command builds the new settings on a copy and stores it only if it succeeded, so a rejected
command leaves everything unchanged.
"""

from __future__ import annotations

import copy
import logging
import math
import warnings
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, Generic, TypeVar

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafContext, LeafSystem

from .exceptions import InvalidInput, SotError, SotWarning, check_name

log = logging.getLogger("sotdrake.entity")

S = TypeVar("S")

#: Recorders of :func:`sotdrake.sequencer.attime`, innermost last.
_recorders: list[list[tuple[Entity, Callable[[Any], None]]]] = []

#: Open :func:`command_group`\ s, innermost last: ``[label, warned]``.
_groups: list[list[Any]] = []


@contextmanager
def command_group(label: str) -> Iterator[None]:
    """The commands of one user command (``gotoNd`` sets a target, a mask and a gain) share one
    warning about a missing ``context=``, which names ``label``."""
    _groups.append([label, False])
    try:
        yield
    finally:
        _groups.pop()


#: Depth of :func:`probing`: contexts made meanwhile are not counted as the user's.
_probing: list[bool] = []


@contextmanager
def probing() -> Iterator[None]:
    """Contexts created inside (e.g. by :func:`sotdrake.stack_checks.check_stack`) do not count as
    contexts the user runs: a later command without ``context=`` does not warn because of them."""
    _probing.append(True)
    try:
        yield
    finally:
        _probing.pop()


def own_context(system: LeafSystem, context: Context) -> Context:
    """``system``'s context, given the root diagram context or its own. (A leaf context is
    validated; a diagram context is the root: asking first whether it is the system's own would
    cost a C++ exception, about a millisecond.)"""
    if not isinstance(context, Context):
        raise InvalidInput(f"{system.get_name()}: context must be a Drake Context of its diagram, got {context!r:.100}")
    try:
        if isinstance(context, LeafContext):
            system.ValidateContext(context)
            return context
        return system.GetMyContextFromRoot(context)
    except RuntimeError:  # a context of another diagram (or of another system)
        raise InvalidInput(f"{system.get_name()}: the context given is not one of the diagram that holds "
                           f"{system.get_name()!r} (a context of another diagram or system)") from None


class _Frozen:
    """The settings held in a Context. A command never changes them in place: it stores a changed
    copy (copy on write), so the copies Drake makes of the state (context clones, the scratch state
    of every unrestricted update) can share them instead of deep-copying them at each tick."""

    __slots__ = ("__weakref__", "value")

    def __init__(self, value: Any):
        self.value = value

    def __deepcopy__(self, memo: dict) -> _Frozen:
        return self


class _DefaultsSnapshot:
    """Model value of the settings state: each copy Drake makes of it (for a new context or a
    ``SetDefaultContext``) holds a deep copy of the owner's defaults *at that moment*."""

    def __init__(self, owner: Entity):
        self.owner = owner

    def __deepcopy__(self, memo: dict) -> _DefaultsSnapshot | _Frozen:
        if self.owner._declaring:
            return _DefaultsSnapshot(self.owner)
        frozen = _Frozen(copy.deepcopy(self.owner._defaults, memo))
        if not _probing:
            self.owner._in_contexts.add(frozen)
        return frozen


class Entity(LeafSystem, Generic[S]):
    """A ``LeafSystem`` named like its SoT entity, with run-time settings in its Context."""

    def __init__(self, name: str, defaults: S):
        check_name(f"{type(self).__name__} name", name)
        LeafSystem.__init__(self)
        self.set_name(name)
        self._defaults = defaults
        # The settings held by live contexts (weak references: a context that is destroyed drops
        # out): while one exists, a change of the defaults does not reach it.
        self._in_contexts: weakref.WeakSet[_Frozen] = weakref.WeakSet()
        self._warned_late_default = False
        #: ``(time, message)`` of each timed command refused during a run (a record, like a log; each
        #: refusal once, however many runs of the diagram met it).
        self.refused_commands: list[tuple[float, str]] = []
        self._declaring = True
        self._settings_index = self.DeclareAbstractState(AbstractValue.Make(_DefaultsSnapshot(self)))
        self._declaring = False

    @property
    def name(self) -> str:
        return self.get_name()

    def own_context(self, context: Context) -> Context:
        """This entity's context, given the root diagram context or its own."""
        return own_context(self, context)

    def settings(self, context: Context | None = None) -> S:
        """The settings in ``context`` (a read-only view), or the defaults without one."""
        if context is None:
            return self._defaults
        return self.own_context(context).get_abstract_state(self._settings_index).get_value().value

    def _settings_of(self, own_context: Context) -> S:
        """Fast read for calc callbacks, which always receive this entity's own context."""
        return own_context.get_abstract_state(self._settings_index).get_value().value

    def _command(self, context: Context | None, change: Callable[[S], None]) -> None:
        if context is not None and _recorders:  # refused before anything changes
            raise SotError(
                f"{self.name}: a command inside attime is recorded and replayed at its time: "
                "call it without context= (got a context)")
        if context is None and _recorders:
            _recorders[-1].append((self, change))
            return
        if context is None:
            new = copy.deepcopy(self._defaults)
            change(new)
            self._defaults = new = copy.deepcopy(new)  # (nothing shared with the caller's arrays)
            if len(self._in_contexts) and not self._warned_late_default:
                self._warn_late_default()
            return
        own = self.own_context(context)
        new = copy.deepcopy(own.get_abstract_state(self._settings_index).get_value().value)
        change(new)
        frozen = _Frozen(copy.deepcopy(new))  # (nothing shared with the caller's arrays)
        self._in_contexts.add(frozen)
        own.get_mutable_abstract_state(self._settings_index).set_value(frozen)

    def _warn_late_default(self) -> None:
        """The warning of a command without ``context=`` once a context exists (see the module
        docstring): once per entity, and once for all the entities of one :func:`command_group`."""
        self._warned_late_default = True
        group = _groups[-1] if _groups else None
        if group is not None and group[1]:
            return
        who = group[0] if group is not None else self.name
        if group is not None:
            group[1] = True
        warnings.warn(
            f"{who}: a command without context= changes the defaults, which only contexts created from now on start "
            "from; a context of this diagram already exists (a Simulator's?) and is NOT changed: pass "
            "context=simulator.get_mutable_context() (or runner.context) to change a running simulation (warned once)",
            SotWarning, stacklevel=4)

    def _declare_timed_change(self, time: float, changes: list[Callable[[S], None]]) -> None:
        """A one-shot event at ``time`` that applies ``changes`` in order (see ``attime``). A change
        refused then (a :class:`SotError`, e.g. removing the last contact) leaves this entity's
        settings as they were, is logged and kept in :attr:`refused_commands`, and the run goes on.
        Each entity has its own event: the parts of one ``attime`` command that go to other entities
        are applied or refused on their own (a Drake system updates its own state only)."""

        def update(context, state):
            value = state.get_mutable_abstract_state(self._settings_index)
            new = copy.deepcopy(value.get_value().value)
            try:
                for change in changes:
                    change(new)
            except SotError as error:
                log.warning("t = %.3f s: %s: its part of a timed command was refused, its settings are unchanged (the "
                            "parts for other entities apply on their own): %s", time, self.name, error)
                refusal = (float(time), str(error))
                if refusal not in self.refused_commands:  # (a diagram run again meets the same refusal: kept once)
                    self.refused_commands.append(refusal)
                return
            frozen = _Frozen(copy.deepcopy(new))
            self._in_contexts.add(frozen)
            value.set_value(frozen)

        # A periodic event whose period outlasts any simulation is a one-shot event at `offset`. It is
        # declared a nanosecond early (more for late times: 16 ulps), so that a command at a tick's time
        # applies at that tick even when the tick's time, k·dt in floating point, falls just below it
        # (with dt = 0.9 ms, tick 11 is at 0.009899999999999999 s; attime(2.0) met the 1 ms tick at 2.0
        # late too).
        early = max(0.0, time - max(1e-9, 16 * math.ulp(time)))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_sec=1e12, offset_sec=early, update=update)


def recording() -> bool:
    """True while :func:`sotdrake.sequencer.attime` records commands."""
    return bool(_recorders)
