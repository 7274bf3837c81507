"""The SoT ``Tracer``: chosen vector signals logged at a chosen period, saved to ``.npz`` and CSV,
and plotted.

Built on Drake's ``LogVectorOutput`` (``VectorLogSink``). A sink publishing at period ``T`` records
the value of its port at each ``k·T`` *before* the discrete updates due at that time (Drake
publishes at the end of the step that reaches ``k·T``, then starts the next one with its updates):
row ``k`` of the device's ``state`` is the configuration its ticks before ``k·T`` produced (with
``T = dt``: row 1 is ``q0 ⊕ v(0)·dt``), the one the tick at ``k·T`` reads, and row ``k`` of the
SoT's ``control`` is the command computed from it, the one that tick integrates (unless an event
due at that very time, a timed command or another system's update, changes it before the tick).

**Streaming.** By default the samples do not stay in memory: every ``chunk`` seconds of simulated
time the sinks' logs are moved to a chunk file (``.npy`` arrays one after the other: the column
names, then each chunk's columns; appended, never re-read while the run goes: no Python objects
pile up for the garbage collector) and cleared, so a long run's memory stays flat. The loops that
flush are :func:`sotdrake.simulation.simulate` (at the run's end too) and the live runner
(:class:`sotdrake.live.runner.LiveRun`); with a ``Simulator`` of your own, call
:func:`flush_tracers` (or :meth:`Tracer.flush`) between ``AdvanceTo`` calls. :meth:`Tracer.data`
reads the chunks back and appends what the logs still hold: the same arrays as with
``stream=False`` (everything in Drake's logs). A file deleted, replaced or changed while a run
streams to it is a :class:`SotError` naming it at the next flush (and in :meth:`Tracer.data`).

**One stream per root context.** Each root context flushed has its own stream while it lives (the
tracer holds it by a weak reference: a context dropped, with its ``Simulator``, drops its stream and
deletes its temporary file, so that many runs through one diagram keep neither memory nor files).
The tracer's file (:attr:`Tracer.path`) holds the latest run: a context flushed from the start of
its run (a new context, or a context run again from an earlier time: its samples before the step
back in time, flushed or not, are dropped) takes it over, and the run it held before moves to a
temporary file, still read by :meth:`Tracer.data` for its context. A
context whose first sample follows a chunk of another context's stream (a ``Context.Clone()``
taken during a run: one period after the chunk's last sample, or at it with the same values)
streams to a temporary file of its own that starts with that stream's chunks up to there:
replaying a clone leaves the original's trace as it was, and the clone's data start at the run's
start.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, LeafContext, OutputPort, System
from pydrake.systems.primitives import LogVectorOutput, VectorLogSink

from .atomic import all_or_nothing, check_vector_port
from .exceptions import InvalidInput, SotError, check_number, os_reason
from .simulation import save_figure, save_npz
from .trace_chunks import ChunkFile, row_digest, stream_path
from .trace_chunks import read_trace as read_trace  # (where the tracer's users look for it)
from .writable import check_writable, writing

#: The tracers that stream, for :func:`flush_tracers` (weak: a tracer dropped is forgotten).
_STREAMING: weakref.WeakSet[Tracer] = weakref.WeakSet()


@dataclass(eq=False)
class _Stream:
    """The chunks of one root context (held by a weak reference: a context gone, its stream goes,
    its temporary file with it): ``file`` (None when they were dropped: ``dropped``), the time of
    the last sample moved there (``last``) and when it was last flushed (the tracer's count)."""

    context_ref: weakref.ref
    file: ChunkFile | None = None
    last: float = -np.inf
    flushed: int = 0
    dropped: bool = False

    @property
    def context(self) -> Context | None:
        return self.context_ref()


class Tracer:
    """sot-core's ``Tracer``: vector output ports logged every ``period`` seconds (see the module
    docstring), saved to ``.npz`` and CSV and plotted.

    ``stream``: ``True`` (default) streams the samples to temporary chunk files, deleted with the
    tracer; a path streams the latest run to that file (kept: read it back with :func:`read_trace`);
    ``False`` keeps every sample in Drake's logs (memory grows with the run). ``chunk``: the
    simulated seconds a chunk holds (> 0)."""

    def __init__(self, builder: DiagramBuilder, period: float, stream: bool | str | Path = True, chunk: float = 1.0):
        if not isinstance(builder, DiagramBuilder):
            raise InvalidInput(f"tracer: expected the DiagramBuilder of the signals, got {type(builder).__name__}")
        period = check_number("tracer period", period, 1e-9, 1e6, " s")
        if not isinstance(stream, bool | str | Path):
            raise InvalidInput(f"tracer stream must be True, False or a file path, got {stream!r}")
        check_number("chunk", chunk, 1e-9, float("inf"), " s")
        taken = [tracer.path for tracer in list(_STREAMING) if tracer.path is not None]
        path = None if isinstance(stream, bool) else stream_path(Path(stream).expanduser(), taken)
        self.builder, self.period, self.chunk = builder, period, float(chunk)
        self.sinks: dict[str, VectorLogSink] = {}
        self._file: ChunkFile | None = None
        if stream is not False:
            try:
                self._file = ChunkFile(path)
            except (OSError, ValueError) as error:  # (a NUL byte in the path: ValueError)
                raise InvalidInput(f"tracer stream: cannot write {str(path)!r}: {os_reason(error)}") from None
            _STREAMING.add(self)
        self._streams: list[_Stream] = []
        self._holder: _Stream | None = None  # the stream whose chunks are in self._file
        self._flushes = 0

    @property
    def path(self) -> Path | None:
        """The chunk file of the latest run (``None`` with ``stream=False``)."""
        return None if self._file is None else self._file.path

    def add(self, port: OutputPort, name: str) -> VectorLogSink:
        """Log ``port`` (a vector output port of a system of this builder) under ``name``; anything
        else is refused with :class:`InvalidInput` and the builder left as it was."""
        if (not isinstance(name, str) or not name or name in self.sinks or name == "time" or "/" in name
                or not name.isprintable()):
            raise InvalidInput(f"tracer: a signal name is a new non-empty string without '/' or control characters, "
                               f"got {name!r:.60}")
        if self.builder.already_built():
            raise SotError(f"tracer: cannot add {name!r}: the diagram is already built (add signals before builder.Build())")
        if any(system.get_name() == f"tracer_{name}" for system in self.builder.GetSystems()):
            raise InvalidInput(f"tracer: another tracer of this diagram logs a signal named {name!r}: give another name")
        check_vector_port(f"tracer: cannot log {name!r}", self.builder, port)
        with all_or_nothing(self.builder):
            sink = LogVectorOutput(port, self.builder, self.period)
            sink.set_name(f"tracer_{name}")
        self.sinks[name] = sink
        return sink

    def flush(self, context: Context, force: bool = False) -> bool:
        """Move the logged samples of the root ``context`` to its stream's file once they span
        ``chunk`` seconds (or with ``force``, whatever they hold); returns whether a chunk was
        written. Samples that do not follow the stream's last ones start a new run (module docstring).
        A ``context`` that is not the diagram's root context: :class:`InvalidInput`, nothing flushed."""
        self._check_context("flush", context)
        if self._file is None or not self.sinks:
            return False
        logs = [sink.FindMutableLog(context) for sink in self.sinks.values()]
        end = _complete(logs)
        times = logs[0].sample_times()[:end]
        start = _run_start(times)
        if times.size == 0 or not (force or times[-1] - times[start] >= self.chunk - 1e-9):
            return False
        stream = self._stream_to_write(context, float(times[start]), _first_row(times, logs, start), restart=start > 0)
        if stream.file is None:  # (its earlier chunks were dropped: the samples stay in Drake's logs)
            return False
        columns = {"time": times[start:].copy(),
                   **{name: log.data()[:, start:end].T.copy() for name, log in zip(self.sinks, logs, strict=True)}}
        stream.file.append(columns, float(times[-1]))
        self._flushes += 1
        stream.last, stream.flushed = float(times[-1]), self._flushes
        for log in logs:
            log.Clear()
        return True

    def _check_context(self, what: str, context: object) -> None:
        _check_root(f"tracer: {what}", next(iter(self.sinks.values()), None), context)

    def _stream_of(self, context: Context) -> _Stream | None:
        return next((stream for stream in self._streams if stream.context is context), None)

    def _stream_to_write(self, context: Context, first: float, first_row: bytes, restart: bool = False) -> _Stream:
        """The stream the samples of ``context`` from time ``first`` on go to: its own if they
        follow it (and are not a ``restart``: the logs went back in time before them), a copy of the
        stream they branch from (a clone), else a new run in the tracer's file."""
        stream = self._stream_of(context)
        if stream is not None and first > stream.last and not restart:
            return stream
        if stream is None:
            stream = _Stream(weakref.ref(context, _forgetter(self)))
            self._streams.append(stream)
            branch = self._branch(context, first, first_row)
            if branch is not None:
                parent, chunks = branch
                assert parent.file is not None
                stream.file, stream.last = parent.file.prefix(chunks), parent.file.ends[chunks - 1]
                return stream
        assert self._file is not None
        if self._holder is not None and self._holder is not stream:
            self._holder.file = self._file.moved_away()
            self._holder.dropped = self._holder.file is None
        else:
            self._file.reset()
        stream.file, stream.last, stream.dropped, self._holder = self._file, -np.inf, False, stream
        return stream

    def _branch(self, context: Context, first: float | None, first_row: bytes | None) -> tuple[_Stream, int] | None:
        """The stream of another context and the number of its chunks that ``context`` continues:
        its first sample (``first``; None when its logs are empty: its time) is one period after the
        end of that chunk, or at it with the same values (``first_row``, :func:`row_digest`: a new
        ``Simulator`` publishes at the clone's time again; a new context set to that time publishes
        its own values). The stream flushed last wins a tie."""
        now = context.get_time() if first is None else first
        tolerance = 1e-9 * max(1.0, abs(now))
        low, high = (now - 1.5 * self.period, now + tolerance) if first is not None else (now - self.period, now + tolerance)
        found = [(stream.flushed, index + 1, stream) for stream in self._streams
                 if stream.context is not context and stream.file is not None
                 for index, end in enumerate(stream.file.ends) if 0 < end and low < end <= high
                 and (first_row is None or end < now - tolerance or stream.file.last_rows[index] == first_row)]
        if not found:
            return None
        _, chunks, stream = max(found, key=lambda item: item[:2])
        return stream, chunks

    def data(self, context: Context) -> dict[str, np.ndarray]:
        """``time`` (k,) and each signal as (k, size): the chunks of ``context``'s stream (or of the
        stream it was cloned from, up to the clone) followed by the samples the sinks' logs in
        ``context`` still hold, one sample per time (the first). :class:`SotError` if the chunks of ``context`` were dropped;
        :class:`InvalidInput` if ``context`` is not the root context of the traced diagram."""
        self._check_context("data", context)
        logs = {name: sink.FindLog(context) for name, sink in self.sinks.items()}
        end = _complete(list(logs.values()))
        times = next(iter(logs.values())).sample_times()[:end] if logs else np.zeros(0)
        start = _run_start(times)  # (the samples before it are an earlier run of this context)
        streamed: dict[str, list[np.ndarray]] = {}
        if self._file is not None and logs:
            first = float(times[start]) if times.size else None
            first_row = _first_row(times, list(logs.values()), start) if times.size else None
            stream = self._stream_of(context)
            if stream is not None and stream.dropped and not start:
                raise SotError(f"tracer: the chunks of this context were dropped when a later run took over "
                               f"{str(self._file.path)!r} (not a regular file, or deleted)")
            if stream is not None and stream.file is not None and (first is None or first > stream.last) and not start:
                streamed = stream.file.read()
            elif stream is None and (branch := self._branch(context, first, first_row)) is not None:
                parent, chunks = branch
                assert parent.file is not None
                streamed = parent.file.read(stop=parent.file.offsets[chunks - 1])
        out: dict[str, np.ndarray] = {"time": np.zeros(0)}  # (a tracer without signals: no time either)
        for name, log in logs.items():
            if name == next(iter(logs)):
                out["time"] = np.concatenate([*streamed.get("time", []), times[start:]])
            tail = log.data()[:, start:end].T
            out[name] = np.concatenate([*streamed.get(name, []), tail]) if streamed else tail.copy()
        repeated = np.flatnonzero(out["time"][1:] == out["time"][:-1]) + 1
        if repeated.size:  # (a new Simulator on a clone publishes at its time again: the first sample holds)
            out = {name: np.delete(values, repeated, axis=0) for name, values in out.items()}
        return out

    def save(self, context: Context, path: Path) -> Path:
        """The data in a ``.npz`` (``np.load``; ``.npz`` appended to ``path`` if it has not that
        suffix), numbers only; returns its path. A path that cannot be written or a ``context`` that
        is not the traced diagram's root context: :class:`InvalidInput`, nothing written."""
        self._check_context("save", context)
        target = check_writable("tracer: save", path)
        if target.suffix != ".npz":
            target = check_writable("tracer: save", target.with_name(target.name + ".npz"))
        data = self.data(context)
        with writing("tracer: save", target):
            return save_npz(target, data)

    def save_csv(self, context: Context, path: Path) -> Path:
        """One CSV: ``time`` then ``<signal>[i]`` columns (every signal shares the period); a name
        holding a comma or a quote is quoted as CSV quotes (RFC 4180). A path that cannot be
        written or a ``context`` that is not the traced diagram's root context: :class:`InvalidInput`."""
        self._check_context("save_csv", context)
        target = check_writable("tracer: save_csv", path)
        data = self.data(context)
        columns = [data["time"][:, None]] + [data[name] for name in self.sinks]
        header = ["time"] + [_csv_field(f"{name}[{i}]") for name in self.sinks for i in range(data[name].shape[1])]
        with writing("tracer: save_csv", target):
            np.savetxt(target, np.hstack(columns), delimiter=",", header=",".join(header), comments="")
        return target

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
        ``name[i]``); signals in ``log`` are drawn on a log scale (as magnitudes). A path that
        cannot be written or a ``context`` that is not the traced diagram's root context:
        :class:`InvalidInput`, checked before drawing."""
        self._check_context("plot", context)
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        target = check_writable("tracer: plot", path)
        data = self.data(context)
        names = signals or list(self.sinks)
        if not names:
            raise InvalidInput("tracer: plot: no signal is traced (Tracer.add a port before the build)")
        labels, legends = labels or {}, legends or {}
        for name in [*names, *labels, *legends, *log]:
            if name not in self.sinks:
                raise InvalidInput(f"tracer: unknown signal {name!r}; traced: {list(self.sinks)}")
        fig, axes = plt.subplots(len(names), 1, figsize=(9, 2.6 * len(names) + 0.6), sharex=True, squeeze=False)
        try:
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
            with writing("tracer: plot", target):
                save_figure(fig, target)
        finally:
            plt.close(fig)
        return target


def _check_root(what: str, system: System | None, context: object) -> None:
    """:class:`InvalidInput` naming ``context`` unless it is the root context of the diagram that
    holds ``system`` (any Context without one), checked before Drake is asked: a null context ends
    the process."""
    need = f"{what}: context must be the root Context of the diagram (diagram.CreateDefaultContext(), simulator.get_context())"
    if not isinstance(context, Context):
        raise InvalidInput(f"{need}, got {type(context).__name__} {context!r:.60}")
    try:
        if system is not None:  # (a root system takes any root context as its own: validated too)
            system.ValidateContext(system.GetMyContextFromRoot(context))
    except RuntimeError:
        got = "a leaf context (of one system)" if isinstance(context, LeafContext) else "another diagram's (or a subdiagram's)"
        raise InvalidInput(f"{need}, got {got}") from None


def _forgetter(tracer: Tracer):
    """The callback of a stream's weak reference to its context: once the context is gone, the
    stream is dropped (its temporary file deleted; the tracer's own file, if the stream held it,
    keeps its chunks for :func:`read_trace`)."""
    tracer_ref = weakref.ref(tracer)

    def forget(context_ref: weakref.ref) -> None:
        owner = tracer_ref()
        if owner is None:
            return
        for stream in [stream for stream in owner._streams if stream.context_ref is context_ref]:
            owner._streams.remove(stream)
            if owner._holder is stream:
                owner._holder = None
            stream.file = None

    return forget


def flush_tracers(diagram: Diagram, context: Context, force: bool = False) -> int:
    """:meth:`Tracer.flush` for every streaming tracer whose sinks are in ``diagram`` (``context``:
    its root context); returns the number of chunks written. A ``diagram`` that is not a built
    ``Diagram`` or a ``context`` that is not its root context: :class:`InvalidInput`, nothing flushed."""
    if not isinstance(diagram, Diagram):
        raise InvalidInput(f"flush_tracers: diagram must be a built Diagram (builder.Build()), got {type(diagram).__name__}")
    _check_root("flush_tracers", diagram, context)
    return sum(tracer.flush(context, force) for tracer in tracers_of(diagram))


def tracers_of(diagram: Diagram) -> list[Tracer]:
    """The streaming tracers whose sinks are systems of ``diagram`` (nested diagrams included)."""
    from .introspection import all_systems

    ids = {id(system) for system in all_systems(diagram)}
    return [tracer for tracer in list(_STREAMING)
            if tracer.sinks and id(next(iter(tracer.sinks.values()))) in ids]


def _csv_field(text: str) -> str:
    """``text`` as one CSV field: quoted (its quotes doubled) if it holds a comma, a quote or a line break."""
    return '"' + text.replace('"', '""') + '"' if any(c in text for c in ',"\r\n') else text


def _first_row(times: np.ndarray, logs: list, start: int = 0) -> bytes:
    """The digest of the logs' sample ``start`` (its time, then each signal's values)."""
    return row_digest([times[start:start + 1], *(log.data()[:, start] for log in logs)])


def _complete(logs: list) -> int:
    """The number of samples every log holds: a run stopped by an error in the middle of a publish
    leaves the sample of that time in some logs only, and it is not a sample of the trace."""
    return min((log.num_samples() for log in logs), default=0)


def _run_start(times: np.ndarray) -> int:
    """The index of the first sample of the latest run in a log's ``times``: the one after the
    last step back in time (a context set to an earlier time and run again), 0 if none."""
    back = np.flatnonzero(times[1:] < times[:-1])
    return int(back[-1]) + 1 if back.size else 0

