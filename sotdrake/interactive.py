"""The seed's interactive workflow: ``python -i diagrams/<script>.py``, then ``next()``, ``step(n)``,
``go(duration)``.

``Runner`` wraps a ``Simulator``: ``next()`` advances one control tick (``device.increment(dt)``),
``step(n)`` n ticks, ``go(duration=None)`` runs for ``duration`` seconds, or until Ctrl-C when None
(the seed's infinite ``go``). Between them, issue commands with ``context=runner.context``
(``sot.push("taskrh", runner.context)``); ``attime`` events in the diagram fire as they come. The
diagram's streaming tracers are flushed as the run goes (:func:`sotdrake.tracing.flush_tracers`),
so that an endless ``go`` keeps its memory flat.
"""

from __future__ import annotations

import math
import numbers
import sys
import time

from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, Diagram

from .exceptions import InvalidInput, finite_number

#: Longest run one ``go`` or ``advance_to`` accepts (s of simulated time): a day.
MAX_DURATION = 86400.0


def _number(name: str, value, low: float, high: float, low_open: bool = False) -> float:
    """``value`` as a float in ``[low, high]`` (``(low, high]`` with ``low_open``), else InvalidInput."""
    ok = finite_number(value)
    if not ok or value > high or value < low or (low_open and value == low):
        bracket = "(" if low_open else "["
        raise InvalidInput(f"{name} must be a number in {bracket}{low:g}, {high:g}], got {value!r}")
    return float(value)


class Runner:
    """A ``Simulator`` driven the seed's way: ``next()``, ``step(n)``, ``go(duration)`` (see the
    module docstring); ``context`` is the root context to give commands."""

    def __init__(self, diagram: Diagram, dt: float, realtime_rate: float = 0.0):
        self.dt = _number("dt", dt, 0.0, 1.0, low_open=True)
        realtime_rate = _number("realtime_rate", realtime_rate, 0.0, 1e6)
        if not isinstance(diagram, Diagram):
            raise InvalidInput(f"Runner: diagram must be a built Diagram (builder.Build()), got {type(diagram).__name__}")
        self.simulator = Simulator(diagram)
        self.simulator.set_target_realtime_rate(realtime_rate)
        self.simulator.Initialize()
        from .tracing import tracers_of  # (here: tracing imports this module's MAX_DURATION through simulation)

        self._tracers = tracers_of(diagram)

    @property
    def context(self) -> Context:
        return self.simulator.get_mutable_context()

    @property
    def t(self) -> float:
        return self.context.get_time()

    def next(self) -> float:
        """One control tick."""
        return self.step(1)

    def step(self, ticks: int = 1) -> float:
        if not isinstance(ticks, numbers.Integral) or isinstance(ticks, bool) or not 0 <= ticks <= MAX_DURATION / self.dt:
            raise InvalidInput(f"ticks must be an integer in [0, {int(MAX_DURATION / self.dt)}], got {ticks!r}")
        # The tick at t is processed when the simulator reaches t: from the last tick reached (now,
        # or before now after advance_to between ticks), ``ticks`` more; never a time in the past.
        target = (math.floor(self.t / self.dt + 1e-6) + ticks) * self.dt
        self._advance(max(self.t, target))
        return self.t

    def advance_to(self, target: float) -> float:
        """Advance to the simulated time ``target`` (s), which must not be earlier than now."""
        self._advance(_number("target", target, self.t, self.t + MAX_DURATION))
        return self.t

    def go(self, duration: float | None = None, chunk: float | None = None) -> float:
        """Run ``duration`` seconds (None: until Ctrl-C), printing the time now and then; the
        simulator advances ``chunk`` seconds at a time (``chunk`` in ``[dt, 60]`` s; None: 0.1 s,
        or one tick when that is longer)."""
        if duration is not None:
            duration = _number("duration", duration, 0.0, MAX_DURATION)
        chunk = max(0.1, self.dt) if chunk is None else _number("chunk", chunk, self.dt, 60.0)
        end = None if duration is None else self.t + duration
        last = time.monotonic()
        try:
            while end is None or self.t < end - 1e-12:
                self._advance(self.t + chunk if end is None else min(self.t + chunk, end))
                if time.monotonic() - last > 1.0:
                    print(f"t = {self.t:.2f} s", file=sys.stderr)
                    last = time.monotonic()
        except KeyboardInterrupt:
            print(f"stopped at t = {self.t:.3f} s", file=sys.stderr)
        for tracer in self._tracers:  # (the files hold everything run so far)
            tracer.flush(self.context, force=True)
        return self.t

    def _advance(self, target: float) -> None:
        if target <= self.t:  # (Drake would process the tick at t now: a clone of the context would process it again)
            return
        self.simulator.AdvanceTo(target)
        for tracer in self._tracers:
            tracer.flush(self.context)
