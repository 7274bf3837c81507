"""The SoT ``Tracer``: chosen vector signals logged at a chosen period, saved to ``.npz`` and CSV,
and plotted.

Built on Drake's ``LogVectorOutput`` (``VectorLogSink``). A sink publishing at period ``T`` records
the value of its port at each ``k·T`` *after* the discrete updates at that time: for the device's
``state`` that is the configuration the tick at ``k·T`` produced.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydrake.systems.framework import Context, DiagramBuilder, OutputPort
from pydrake.systems.primitives import LogVectorOutput, VectorLogSink

from .exceptions import InvalidInput


class Tracer:
    def __init__(self, builder: DiagramBuilder, period: float):
        if not period > 0:
            raise InvalidInput(f"tracer period must be > 0, got {period}")
        self.builder, self.period = builder, period
        self.sinks: dict[str, VectorLogSink] = {}

    def add(self, port: OutputPort, name: str) -> VectorLogSink:
        """Log ``port`` (a vector output) under ``name``."""
        if name in self.sinks or name == "time":
            raise InvalidInput(f"tracer: signal name {name!r} is already used")
        sink = LogVectorOutput(port, self.builder, self.period)
        sink.set_name(f"tracer_{name}")
        self.sinks[name] = sink
        return sink

    def data(self, context: Context) -> dict[str, np.ndarray]:
        """``time`` (k,) and each signal as (k, size), from the sinks' logs in ``context``."""
        out: dict[str, np.ndarray] = {}
        for name, sink in self.sinks.items():
            log = sink.FindLog(context)
            out.setdefault("time", log.sample_times().copy())
            out[name] = log.data().T.copy()
        return out

    def save(self, context: Context, path: Path) -> Path:
        np.savez_compressed(path, **self.data(context))
        return Path(path)

    def save_csv(self, context: Context, path: Path) -> Path:
        """One CSV: ``time`` then ``<signal>[i]`` columns (every signal shares the period)."""
        data = self.data(context)
        columns = [data["time"][:, None]] + [data[name] for name in self.sinks]
        header = ["time"] + [f"{name}[{i}]" for name in self.sinks for i in range(data[name].shape[1])]
        np.savetxt(path, np.hstack(columns), delimiter=",", header=",".join(header), comments="")
        return Path(path)

    def plot(self, context: Context, path: Path, signals: list[str] | None = None) -> Path:
        """A PNG with one panel per signal (default: all) against time."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        data = self.data(context)
        names = signals or list(self.sinks)
        for name in names:
            if name not in self.sinks:
                raise InvalidInput(f"tracer: unknown signal {name!r}; traced: {list(self.sinks)}")
        fig, axes = plt.subplots(len(names), 1, figsize=(8, 2.2 * len(names)), sharex=True, squeeze=False)
        for axis, name in zip(axes[:, 0], names):
            axis.plot(data["time"], data[name])
            axis.set_ylabel(name)
        axes[-1, 0].set_xlabel("time (s)")
        fig.tight_layout()
        fig.savefig(path, dpi=100)
        plt.close(fig)
        return Path(path)
