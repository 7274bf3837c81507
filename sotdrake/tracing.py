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
from .simulation import save_figure


class Tracer:
    """sot-core's ``Tracer``: vector output ports logged every ``period`` seconds (see the module
    docstring), saved to ``.npz`` and CSV and plotted."""

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
        np.savez_compressed(path, allow_pickle=False, **self.data(context))  # numbers only
        return Path(path)

    def save_csv(self, context: Context, path: Path) -> Path:
        """One CSV: ``time`` then ``<signal>[i]`` columns (every signal shares the period)."""
        data = self.data(context)
        columns = [data["time"][:, None]] + [data[name] for name in self.sinks]
        header = ["time"] + [f"{name}[{i}]" for name in self.sinks for i in range(data[name].shape[1])]
        np.savetxt(path, np.hstack(columns), delimiter=",", header=",".join(header), comments="")
        return Path(path)

    def plot(
        self,
        context: Context,
        path: Path,
        signals: list[str] | None = None,
        title: str | None = None,
        labels: dict[str, str] | None = None,
        legends: dict[str, list[str]] | None = None,
        log: tuple[str, ...] = (),
    ) -> Path:
        """A PNG with one panel per signal (default: all) against time (s). ``title``: the figure's
        title; ``labels``: each panel's y label, with its unit (default: the signal's name);
        ``legends``: the names of a signal's components (default: the signal's name, or
        ``name[i]``); signals in ``log`` are drawn on a log scale (as magnitudes)."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        data = self.data(context)
        names = signals or list(self.sinks)
        labels, legends = labels or {}, legends or {}
        for name in [*names, *labels, *legends, *log]:
            if name not in self.sinks:
                raise InvalidInput(f"tracer: unknown signal {name!r}; traced: {list(self.sinks)}")
        fig, axes = plt.subplots(len(names), 1, figsize=(9, 2.6 * len(names) + 0.6), sharex=True, squeeze=False)
        for axis, name in zip(axes[:, 0], names, strict=False):
            values = data[name]
            components = legends.get(name) or ([name] if values.shape[1] == 1 else
                                               [f"{name}[{i}]" for i in range(values.shape[1])])
            if len(components) != values.shape[1]:
                raise InvalidInput(f"tracer: {name} has {values.shape[1]} components, the legend names {len(components)}")
            if name in log:
                axis.semilogy(data["time"], np.maximum(np.abs(values), 1e-16))
            else:
                axis.plot(data["time"], values)
            axis.set_ylabel(labels.get(name, name))
            axis.legend(components, fontsize=7, ncol=1 + len(components) // 8, loc="best")
            axis.grid(True, alpha=0.3)
        axes[-1, 0].set_xlabel("time (s)")
        if title:
            fig.suptitle(title)
        return save_figure(fig, path)
