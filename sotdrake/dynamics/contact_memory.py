"""What ``SolverDyn`` keeps from one tick to the next: one discrete-state vector of its Context.

A discrete update is computed from the same context as the device's and the plant's step (the
physical plant's step is a discrete update too: its output ports are not sampled, see
:func:`sotdrake.physics.add_physical_talos`), so every system of a tick sees the same record, and
the record is that of the solve whose torque the tick applies. The vector holds, per declared
contact (declaration order): the normal force it carried at the last tick (N; NaN: not held),
which weighs the shear regularization (:func:`.formulation.shear_weights`); the bounds held at the
last tick's optimum (:data:`.formulation.HELD_BOUNDS` signed entries,
:func:`.formulation.held_bounds`), where the QR path starts (a guess: the answer does not depend on
it); and each contact's release ramp ``(t0, f0, k)`` (s, N, the release's number; NaN: none).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from pydrake.systems.framework import Context, LeafSystem

from .formulation import HELD_BOUNDS


def memory_slices(max_contacts: int) -> tuple[slice, slice, slice]:
    """Where the loads, the held bounds and the ramps lie in the discrete state."""
    return (slice(0, max_contacts), slice(max_contacts, max_contacts + HELD_BOUNDS),
            slice(max_contacts + HELD_BOUNDS, 4 * max_contacts + HELD_BOUNDS))


class ContactMemory:
    """The record of the module docstring, declared on ``system`` (a discrete state updated every
    ``dt`` s by ``update(context, state)``, which calls :meth:`record`)."""

    def __init__(self, system: LeafSystem, max_contacts: int, dt: float, update: Callable[[Context, Any], None]):
        self.loads, self.held, self.ramps = memory_slices(max_contacts)
        memory = np.full(self.ramps.stop, np.nan)
        memory[self.held] = 0.0
        self.index = system.DeclareDiscreteState(memory)
        system.DeclarePeriodicDiscreteUpdateEvent(dt, 0.0, update)

    def _values(self, context: Context) -> np.ndarray:
        return context.get_discrete_state(self.index).get_value()

    def ramp(self, context: Context, contact: int) -> tuple[float, float]:
        """``(t0, f0)`` of the ``contact``-th declared contact's release ramp (NaN: none)."""
        i = self.ramps.start + 3 * contact
        memory = self._values(context)
        return float(memory[i]), float(memory[i + 1])

    def held_bound_guess(self, context: Context) -> np.ndarray:
        """The bounds held at the last tick's optimum (:func:`.formulation.held_bounds`)."""
        return self._values(context)[self.held].copy()

    def previous_loads(self, context: Context, contacts: list[int]) -> list[float] | None:
        """The normal force (N) each of the declared ``contacts`` carried at the previous tick, as
        Python floats, or None if one of them was not held then."""
        record = self._values(context)[self.loads].tolist()  # a few floats
        loads = [record[i] for i in contacts]
        return loads if all(math.isfinite(f) for f in loads) else None

    def record(self, state: Any, time: float, loads: list[float], releases: list[int | None], held_bounds: np.ndarray) -> None:
        """Into the discrete ``state``: each declared contact's normal force (``loads``, NaN: not
        held) and the bounds held at the optimum; the ramp of a newly released contact (``releases``:
        the number of its release, None when it is not being released) starts now from the force it
        carries, a contact not released has none."""
        memory = state.get_mutable_value(self.index)  # initialized to the current state: changed in place
        for i, (load, release) in enumerate(zip(loads, releases, strict=True)):
            memory[self.loads.start + i] = load
            r = self.ramps.start + 3 * i
            if release is None:
                memory[r : r + 3] = math.nan
            elif memory[r + 2] != release:  # (NaN: no ramp yet)
                memory[r], memory[r + 1], memory[r + 2] = time, 0.0 if math.isnan(load) else load, release
        memory[self.held] = held_bounds
