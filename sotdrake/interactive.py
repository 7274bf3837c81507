"""The seed's interactive workflow: ``python -i diagrams/<script>.py``, then ``next()``, ``step(n)``,
``go(duration)``.

``Runner`` wraps a ``Simulator``: ``next()`` advances one control tick (``device.increment(dt)``),
``step(n)`` n ticks, ``go(duration=None)`` runs for ``duration`` seconds, or until Ctrl-C when None
(the seed's infinite ``go``). Between them, issue commands with ``context=runner.context``
(``sot.push("taskrh", runner.context)``); ``attime`` events in the diagram fire as they come.
"""

from __future__ import annotations

import sys
import time

from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, Diagram

from .exceptions import InvalidInput


class Runner:
    def __init__(self, diagram: Diagram, dt: float, realtime_rate: float = 0.0):
        if not dt > 0:
            raise InvalidInput(f"dt must be > 0, got {dt}")
        self.dt = dt
        self.simulator = Simulator(diagram)
        self.simulator.set_target_realtime_rate(realtime_rate)
        self.simulator.Initialize()

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
        if ticks < 0:
            raise InvalidInput(f"cannot step {ticks} ticks backwards")
        # The tick at t is processed when the simulator reaches t; land just before the next one.
        target = (round(self.t / self.dt) + ticks) * self.dt
        self.simulator.AdvanceTo(target)
        return self.t

    def go(self, duration: float | None = None, chunk: float = 0.1) -> float:
        """Run ``duration`` seconds (None: until Ctrl-C), printing the time now and then."""
        end = None if duration is None else self.t + duration
        last = time.monotonic()
        try:
            while end is None or self.t < end - 1e-12:
                self.simulator.AdvanceTo(self.t + chunk if end is None else min(self.t + chunk, end))
                if time.monotonic() - last > 1.0:
                    print(f"t = {self.t:.2f} s", file=sys.stderr)
                    last = time.monotonic()
        except KeyboardInterrupt:
            print(f"stopped at t = {self.t:.3f} s", file=sys.stderr)
        return self.t
