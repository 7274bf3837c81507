"""The SoT ``Tracer``: chosen vector signals logged at a chosen period, saved to ``.npz`` and CSV,
and plotted.

Built on Drake's ``LogVectorOutput`` (``VectorLogSink``). A sink publishing at period ``T`` records
the value of its port at each ``k·T`` *after* the discrete updates at that time: for the device's
``state`` that is the configuration the tick at ``k·T`` produced.

**Streaming.** By default the samples do not stay in memory: every ``chunk`` seconds of simulated
time the sinks' logs are moved to a chunk file (``.npy`` arrays one after the other: the column
names, then each chunk's columns; appended, never re-read while the run goes: no Python objects
pile up for the garbage collector) and cleared, so a long run's memory stays flat. The loops that
flush are
:func:`sotdrake.simulation.simulate` and the live runner (:class:`sotdrake.live.runner.LiveRun`);
with a ``Simulator`` of your own, call :func:`flush_tracers` (or :meth:`Tracer.flush`) between
``AdvanceTo`` calls. :meth:`Tracer.data` reads the chunks back and appends what the logs still
hold: the same arrays as with ``stream=False`` (everything in Drake's logs). The file belongs to
the context flushed first; flushing another root context starts it over.
"""

from __future__ import annotations

import logging
import tempfile
import weakref
from pathlib import Path

import numpy as np
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, OutputPort
from pydrake.systems.primitives import LogVectorOutput, VectorLogSink

from .exceptions import InvalidInput, SotError, check_number, os_reason
from .simulation import save_figure, save_npz

log = logging.getLogger(__name__)

#: The tracers that stream, for :func:`flush_tracers` (weak: a tracer dropped is forgotten).
_STREAMING: weakref.WeakSet[Tracer] = weakref.WeakSet()


class _ChunkFile:
    """A sequence of ``.npy`` arrays in one file, appended to: the column names (a string array),
    then per chunk one array per column in that order. Nothing is re-read when a chunk is added."""

    def __init__(self, path: Path | None):
        self._temporary = None
        if path is None:  # deleted with this object
            self._temporary = tempfile.NamedTemporaryFile(prefix="sotdrake-trace-", suffix=".npys")
            path = Path(self._temporary.name)
        self.path = Path(path)
        self.chunks = 0
        self.reset()

    def reset(self) -> None:
        self.path.write_bytes(b"")
        self.chunks = 0

    def append(self, columns: dict[str, np.ndarray]) -> None:
        with open(self.path, "ab") as file:
            if self.chunks == 0:
                np.lib.format.write_array(file, np.array(list(columns), dtype=str), allow_pickle=False)
            for values in columns.values():
                np.lib.format.write_array(file, np.ascontiguousarray(values), allow_pickle=False)
        self.chunks += 1

    def read(self) -> dict[str, list[np.ndarray]]:
        """Each column's chunks, in order: the complete ones (a chunk cut short, by a run stopped
        while it was being written, is left out with a warning)."""
        try:
            size = self.path.stat().st_size
        except OSError as error:
            raise InvalidInput(f"trace file {str(self.path)!r}: {error.strerror}") from None
        with open(self.path, "rb") as file:
            if size == 0:
                return {}
            try:
                names = [str(name) for name in np.lib.format.read_array(file, allow_pickle=False)]
            except ValueError as error:
                raise InvalidInput(f"{self.path}: not a trace file ({error})") from None
            out: dict[str, list[np.ndarray]] = {name: [] for name in names}
            while file.tell() < size:
                start = file.tell()
                try:
                    chunk = [np.lib.format.read_array(file, allow_pickle=False) for _ in names]
                except ValueError:
                    log.warning("%s: the chunk at byte %d is cut short (a run stopped while writing it): read up to "
                                "there", self.path, start)
                    break
                for name, values in zip(names, chunk, strict=True):
                    out[name].append(values)
        return out


class Tracer:
    """sot-core's ``Tracer``: vector output ports logged every ``period`` seconds (see the module
    docstring), saved to ``.npz`` and CSV and plotted.

    ``stream``: ``True`` (default) streams the samples to a temporary chunk file, deleted with the
    tracer; a path streams to that file (kept: read it back with :func:`read_trace`); ``False``
    keeps every sample in Drake's logs (memory grows with the run). ``chunk``: the simulated
    seconds a chunk holds (> 0)."""

    def __init__(self, builder: DiagramBuilder, period: float, stream: bool | str | Path = True, chunk: float = 1.0):
        period = check_number("tracer period", period, 1e-9, 1e6, " s")
        if not isinstance(stream, bool | str | Path):
            raise InvalidInput(f"tracer stream must be True, False or a file path, got {stream!r}")
        check_number("chunk", chunk, 1e-9, float("inf"), " s")
        path = None if isinstance(stream, bool) else _stream_path(Path(stream).expanduser())
        self.builder, self.period, self.chunk = builder, period, float(chunk)
        self.sinks: dict[str, VectorLogSink] = {}
        self._file: _ChunkFile | None = None
        if stream is not False:
            try:
                self._file = _ChunkFile(path)
            except (OSError, ValueError) as error:  # (a NUL byte in the path: ValueError)
                raise InvalidInput(f"tracer stream: cannot write {str(path)!r}: {os_reason(error)}") from None
            _STREAMING.add(self)
        self._owner: int | None = None  # id of the root context the file holds
        self._last = -np.inf  # the time of the last sample moved to the file

    @property
    def path(self) -> Path | None:
        """The chunk file (``None`` with ``stream=False``)."""
        return None if self._file is None else self._file.path

    def add(self, port: OutputPort, name: str) -> VectorLogSink:
        """Log ``port`` (a vector output) under ``name``."""
        if (not isinstance(name, str) or not name or name in self.sinks or name == "time" or "/" in name
                or not name.isprintable()):
            raise InvalidInput(f"tracer: a signal name is a new non-empty string without '/' or control characters, "
                               f"got {name!r:.60}")
        if self.builder.already_built():
            raise SotError(f"tracer: cannot add {name!r}: the diagram is already built (add signals before builder.Build())")
        if any(system.get_name() == f"tracer_{name}" for system in self.builder.GetSystems()):
            raise InvalidInput(f"tracer: another tracer of this diagram logs a signal named {name!r}: give another name")
        sink = LogVectorOutput(port, self.builder, self.period)
        sink.set_name(f"tracer_{name}")
        self.sinks[name] = sink
        return sink

    def flush(self, context: Context, force: bool = False) -> bool:
        """Move the logged samples of the root ``context`` to the file once they span ``chunk``
        seconds (or with ``force``, whatever they hold); returns whether a chunk was written."""
        if self._file is None or not self.sinks:
            return False
        logs = [sink.FindMutableLog(context) for sink in self.sinks.values()]
        times = logs[0].sample_times()
        if times.size == 0 or not (force or times[-1] - times[0] >= self.chunk - 1e-9):
            return False
        if self._owner != id(context) or times[0] <= self._last:  # another context, or a rerun
            self._file.reset()
        self._owner, self._last = id(context), float(times[-1])
        columns = {"time": times.copy(), **{name: log.data().T.copy() for name, log in zip(self.sinks, logs, strict=True)}}
        self._file.append(columns)
        for log in logs:
            log.Clear()
        return True

    def data(self, context: Context) -> dict[str, np.ndarray]:
        """``time`` (k,) and each signal as (k, size): the file's chunks (if they belong to
        ``context``) followed by the samples the sinks' logs in ``context`` still hold."""
        streamed = {}
        if self._file is not None and self._owner == id(context) and self._file.chunks and self.sinks:
            times = next(iter(self.sinks.values())).FindLog(context).sample_times()
            if times.size == 0 or times[0] > self._last:  # not a rerun since the last flush
                streamed = self._file.read()
        out: dict[str, np.ndarray] = {}
        for name, sink in self.sinks.items():
            log = sink.FindLog(context)
            out.setdefault("time", np.concatenate([*streamed.get("time", []), log.sample_times()]))
            tail = log.data().T
            out[name] = np.concatenate([*streamed.get(name, []), tail]) if streamed else tail.copy()
        return out

    def save(self, context: Context, path: Path) -> Path:
        """The data in a ``.npz`` (``np.load``), numbers only; returns its path."""
        return save_npz(path, self.data(context))

    def save_csv(self, context: Context, path: Path) -> Path:
        """One CSV: ``time`` then ``<signal>[i]`` columns (every signal shares the period); a name
        holding a comma or a quote is quoted as CSV quotes (RFC 4180)."""
        data = self.data(context)
        columns = [data["time"][:, None]] + [data[name] for name in self.sinks]
        header = ["time"] + [_csv_field(f"{name}[{i}]") for name in self.sinks for i in range(data[name].shape[1])]
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


def _stream_path(path: Path) -> Path:
    """``path`` if a tracer may stream to it: a file in an existing folder, no other tracer's, and
    either new, empty or a trace file already (a file of another kind is not overwritten)."""
    try:
        if path.is_dir() or not path.parent.is_dir():
            raise InvalidInput(f"tracer stream: {str(path)!r} is a folder or its folder does not exist: give a file path")
        if any(tracer.path is not None and tracer.path.resolve() == path.resolve() for tracer in list(_STREAMING)):
            raise InvalidInput(f"tracer stream: another tracer streams to {str(path)!r}")
        if path.is_file() and path.stat().st_size:
            with open(path, "rb") as file:
                try:
                    np.lib.format.read_array(file, allow_pickle=False)
                except ValueError:
                    raise InvalidInput(f"tracer stream: {str(path)!r} exists and is not a trace file: not overwritten") from None
    except SotError:
        raise
    except (OSError, ValueError) as error:  # (a NUL byte in the path: ValueError)
        raise InvalidInput(f"tracer stream: {str(path)!r}: {os_reason(error)}") from None
    return path


def flush_tracers(diagram: Diagram, context: Context, force: bool = False) -> int:
    """:meth:`Tracer.flush` for every streaming tracer whose sinks are in ``diagram`` (``context``:
    its root context); returns the number of chunks written."""
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


def read_trace(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays of a chunk file a tracer streamed to (``time`` and each signal, concatenated; empty
    when the file was cut inside its first chunk, with a warning)."""
    if not isinstance(path, str | Path):
        raise InvalidInput(f"read_trace: a file path, got {path!r:.60}")
    reader = _ChunkFile.__new__(_ChunkFile)
    reader.path = Path(path)
    if reader.path.is_dir():
        raise InvalidInput(f"read_trace: {str(path)!r} is a folder, not a trace file")
    return {name: np.concatenate(parts) if parts else np.zeros((0,) if name == "time" else (0, 0))
            for name, parts in reader.read().items()}
