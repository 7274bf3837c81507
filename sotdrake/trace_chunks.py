"""The tracer's chunk files: ``.npy`` arrays one after the other in one file (the column names, then
each chunk's columns), appended while a run goes and read back whole or up to a chunk, and
:func:`read_trace`, which reads a finished file."""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import tempfile
import weakref
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from .exceptions import InvalidInput, SotError

log = logging.getLogger("sotdrake.tracing")


class ChunkFile:
    """A sequence of ``.npy`` arrays in one file, appended to: the column names (a string array),
    then per chunk one array per column in that order. Nothing is re-read when a chunk is added;
    the byte offset, the last sample time and a digest of the last row (:func:`row_digest`) of each
    chunk are kept."""

    def __init__(self, path: Path | None):
        if path is None:  # deleted with this object (or at exit), no file left open
            handle, name = tempfile.mkstemp(prefix="sotdrake-trace-", suffix=".npys")
            os.close(handle)
            path = Path(name)
            weakref.finalize(self, path.unlink, missing_ok=True)
        self.path = Path(path)
        self.chunks = 0
        self.offsets: list[int] = []
        self.ends: list[float] = []
        self.last_rows: list[bytes] = []
        self.reset()

    def reset(self) -> None:
        self.path.write_bytes(b"")
        self.chunks, self.offsets, self.ends, self.last_rows = 0, [], [], []

    def append(self, columns: dict[str, np.ndarray], end: float | None = None) -> None:
        """Write one chunk; ``end``: the time of its last sample (default: the last ``time``)."""
        if end is None:
            times = np.asarray(columns.get("time", ()))
            end = float(times[-1]) if times.size else float("nan")
        with open(self.path, "ab") as file:
            if self.chunks == 0:
                np.lib.format.write_array(file, np.array(list(columns), dtype=str), allow_pickle=False)
            for values in columns.values():
                np.lib.format.write_array(file, np.ascontiguousarray(values), allow_pickle=False)
            offset = file.tell()
        self.chunks += 1
        self.offsets.append(offset)
        self.ends.append(end)
        self.last_rows.append(row_digest(values[-1] for values in columns.values()))

    def prefix(self, chunks: int) -> ChunkFile:
        """A temporary file holding this file's first ``chunks`` chunks."""
        copy = ChunkFile(None)
        with open(self.path, "rb") as source, open(copy.path, "wb") as target:
            remaining = self.offsets[chunks - 1]
            while remaining > 0:
                block = source.read(min(remaining, 1 << 22))
                if not block:
                    raise SotError(f"trace file {str(self.path)!r} is shorter than the chunks written to it")
                target.write(block)
                remaining -= len(block)
        copy.chunks, copy.offsets, copy.ends = chunks, self.offsets[:chunks], self.ends[:chunks]
        copy.last_rows = self.last_rows[:chunks]
        return copy

    def moved_away(self) -> ChunkFile | None:
        """This file's chunks moved to a temporary file (this file is then empty), or None when this
        is not a regular file (a device: its chunks cannot be read back) and the chunks are dropped."""
        if not self.path.is_file():
            self.reset()
            return None
        moved = ChunkFile(None)
        shutil.move(str(self.path), str(moved.path))
        moved.chunks, moved.offsets, moved.ends, moved.last_rows = self.chunks, self.offsets, self.ends, self.last_rows
        self.reset()
        return moved

    def read(self, stop: int | None = None) -> dict[str, list[np.ndarray]]:
        """Each column's chunks, in order (up to byte ``stop`` if given): the complete ones (a chunk
        cut short, by a run stopped while it was being written, is left out with a warning)."""
        try:
            size = self.path.stat().st_size
        except OSError as error:
            raise InvalidInput(f"trace file {str(self.path)!r}: {error.strerror}") from None
        size = size if stop is None else min(size, stop)
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


def row_digest(values: Iterable[np.ndarray]) -> bytes:
    """A digest of one sample row (the time, then each signal's values): two rows with the same
    digest hold the same numbers."""
    digest = hashlib.blake2b(digest_size=16)
    for value in values:
        digest.update(np.ascontiguousarray(value, dtype=float).tobytes())
    return digest.digest()


def read_trace(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays of a chunk file a tracer streamed to (``time`` and each signal, concatenated; empty
    when the file was cut inside its first chunk, with a warning)."""
    if not isinstance(path, str | Path):
        raise InvalidInput(f"read_trace: a file path, got {path!r:.60}")
    reader = ChunkFile.__new__(ChunkFile)
    reader.path = Path(path)
    if reader.path.is_dir():
        raise InvalidInput(f"read_trace: {str(path)!r} is a folder, not a trace file")
    return {name: np.concatenate(parts) if parts else np.zeros((0,) if name == "time" else (0, 0))
            for name, parts in reader.read().items()}
