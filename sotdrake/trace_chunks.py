"""The tracer's chunk files: ``.npy`` arrays one after the other in one file (the column names, then
each chunk's columns), appended while a run goes and read back whole or up to a chunk, and
:func:`read_trace`, which reads a finished file.

A file is read as a trace only if it is one: its first array is a 1-D array of distinct column
names, then each chunk holds one float array per column, the rows of one chunk in equal number
(``time`` 1-D, every other column with the shape of its first chunk). Anything else, a corrupted
header included, is an :class:`InvalidInput` (``not a trace file``, or the byte where the chunks
stop making sense); only a file that ends inside a chunk or right after its names (a run stopped
while writing) reads up to there, with a warning."""

from __future__ import annotations

import hashlib
import io
import logging
import math
import os
import shutil
import stat
import tempfile
import tokenize
import warnings
import weakref
from collections.abc import Iterable
from pathlib import Path
from typing import BinaryIO

import numpy as np

from .exceptions import InvalidInput, SotError, os_reason

log = logging.getLogger("sotdrake.tracing")

#: The ``.npy`` versions read (the bytes of their header length): those numpy writes such arrays in.
_VERSIONS = {(1, 0): 2, (2, 0): 4}
#: What numpy's header parsing raises on a header that is not one (a corrupted byte can make any of these).
_HEADER_ERRORS = (ValueError, SyntaxError, TypeError, KeyError, OverflowError, RecursionError, MemoryError,
                  tokenize.TokenError, Warning)


class ChunkFile:
    """A sequence of ``.npy`` arrays in one file, appended to: the column names (a string array),
    then per chunk one array per column in that order. Nothing is re-read when a chunk is added;
    the byte offset, the last sample time and a digest of the last row (:func:`row_digest`) of each
    chunk are kept. A chunk is appended only to the file this object wrote, as it left it: a file
    deleted, replaced or changed in between is a :class:`SotError` naming it, nothing written."""

    def __init__(self, path: Path | None, *, existing: bool = False):
        """``path`` None: a temporary file. ``existing``: read the file as it is (for :meth:`read`;
        nothing is written), instead of starting it empty."""
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
        self._own = not existing  # (a file this object writes: read only as it left it)
        self._identity: tuple[int, int] | None = None  # (device, inode) of the file written, once a chunk is
        if not existing:
            self.reset()

    def reset(self) -> None:
        """Start the file over, empty (a new run): :class:`SotError` if another file replaced the one
        written (it is left as it is)."""
        if self._identity is not None and self.path.exists():
            self._check_intact(replaced_only=True)
        self.path.write_bytes(b"")
        self.chunks, self.offsets, self.ends, self.last_rows = 0, [], [], []
        self._identity = None

    def append(self, columns: dict[str, np.ndarray], end: float | None = None) -> None:
        """Write one chunk; ``end``: the time of its last sample (default: the last ``time``)."""
        if end is None:
            times = np.asarray(columns.get("time", ()))
            end = float(times[-1]) if times.size else float("nan")
        with self._open_to_append() as file:
            if self.chunks == 0:
                np.lib.format.write_array(file, np.array(list(columns), dtype=str), allow_pickle=False)
            for values in columns.values():
                np.lib.format.write_array(file, np.ascontiguousarray(values), allow_pickle=False)
            offset = file.tell()
        self.chunks += 1
        self.offsets.append(offset)
        self.ends.append(end)
        self.last_rows.append(row_digest(values[-1] for values in columns.values()))

    def _open_to_append(self) -> BinaryIO:
        """The file opened at its end, checked to be the one written so far, as it was left."""
        flags = os.O_WRONLY | os.O_APPEND | (os.O_CREAT if self.chunks == 0 else 0)
        try:
            handle = os.open(self.path, flags, 0o666)
        except FileNotFoundError:
            raise SotError(self._lost("was deleted")) from None
        file = os.fdopen(handle, "ab")
        status = os.fstat(handle)
        changed = self._changed(status)
        if changed is not None:
            file.close()
            raise SotError(self._lost(changed))
        self._identity = (status.st_dev, status.st_ino)
        return file

    def _changed(self, status: os.stat_result, replaced_only: bool = False) -> str | None:
        """How the file (its ``status``) differs from what this object wrote there, None if it does not."""
        written = self.offsets[-1] if self.chunks else 0
        if self._identity is not None and (status.st_dev, status.st_ino) != self._identity:
            return "was replaced by another file"
        if stat.S_ISREG(status.st_mode) and status.st_size != written and not replaced_only:
            return f"holds {status.st_size} bytes, not the {written} written"
        return None

    def _check_intact(self, replaced_only: bool = False) -> None:
        """:class:`SotError` unless the file is the one this object wrote, as it left it."""
        try:
            changed = self._changed(self.path.stat(), replaced_only)
        except FileNotFoundError:
            changed = "was deleted"
        if changed is not None:
            raise SotError(self._lost(changed))

    def _note_identity(self) -> None:
        status = self.path.stat()
        self._identity = (status.st_dev, status.st_ino)

    def _lost(self, how: str) -> str:
        return (f"trace file {str(self.path)!r} {how} while a run streamed to it: the {self.chunks} chunk(s) of the run "
                "written there are lost, and nothing more is written there (stream to a file nothing else touches)")

    def prefix(self, chunks: int) -> ChunkFile:
        """A temporary file holding this file's first ``chunks`` chunks."""
        self._check_intact()
        copy = ChunkFile(None)
        try:
            with open(self.path, "rb") as source, open(copy.path, "wb") as target:
                remaining = self.offsets[chunks - 1]
                while remaining > 0:
                    block = source.read(min(remaining, 1 << 22))
                    if not block:
                        raise SotError(f"trace file {str(self.path)!r} is shorter than the chunks written to it")
                    target.write(block)
                    remaining -= len(block)
        except FileNotFoundError:
            raise SotError(self._lost("was deleted")) from None
        copy.chunks, copy.offsets, copy.ends = chunks, self.offsets[:chunks], self.ends[:chunks]
        copy.last_rows = self.last_rows[:chunks]
        copy._note_identity()
        return copy

    def moved_away(self) -> ChunkFile | None:
        """This file's chunks moved to a temporary file (this file is then empty), or None when this
        is not a regular file (a device: its chunks cannot be read back) and the chunks are dropped."""
        if not self.path.is_file():
            self.reset()
            return None
        self._check_intact()  # (another file there is not moved away, nor emptied)
        moved = ChunkFile(None)
        shutil.move(str(self.path), str(moved.path))
        moved.chunks, moved.offsets, moved.ends, moved.last_rows = self.chunks, self.offsets, self.ends, self.last_rows
        moved._note_identity()
        self.reset()
        return moved

    def read(self, stop: int | None = None) -> dict[str, list[np.ndarray]]:
        """Each column's chunks, in order (up to byte ``stop`` if given): the complete ones (a chunk
        cut short, by a run stopped while it was being written, is left out with a warning). A file
        that is not a trace file (module docstring): :class:`InvalidInput`; this object's own file
        deleted or changed since it wrote it: :class:`SotError`."""
        if self._own and self.chunks == 0:
            return {}
        if self._own:
            self._check_intact()
        try:
            size = self.path.stat().st_size
            size = size if stop is None else min(size, stop)
            if size == 0:
                return {}
            with open(self.path, "rb") as file:
                try:
                    names = _read_names(file, size)
                except ValueError as error:
                    raise InvalidInput(f"{str(self.path)!r}: not a trace file ({error})") from None
                out: dict[str, list[np.ndarray]] = {name: [] for name in names}
                if file.tell() == size and stop is None:
                    log.warning("%s: no chunk after the column names (a run stopped before writing its first one)", self.path)
                while file.tell() < size:
                    start = file.tell()
                    try:
                        chunk = _read_chunk(file, size, out)
                    except _CutShort:
                        log.warning("%s: the chunk at byte %d is cut short (a run stopped while writing it): read up to "
                                    "there", self.path, start)
                        break
                    except ValueError as error:
                        raise InvalidInput(f"trace file {str(self.path)!r}: corrupted at the chunk at byte {start} "
                                           f"({error}): not read") from None
                    for name, values in zip(names, chunk, strict=True):
                        out[name].append(values)
        except OSError as error:
            raise InvalidInput(f"trace file {str(self.path)!r}: {error.strerror}") from None
        return out


class _CutShort(Exception):
    """The file ends inside the array being read."""


def _read_array(file: BinaryIO, size: int) -> np.ndarray:
    """The ``.npy`` array at the position of ``file`` (whose data end at byte ``size``), its header
    checked before anything is allocated: :class:`_CutShort` if the data end inside it, ValueError
    if there is no such array there (not a ``.npy`` header, an object array, a Fortran-ordered one)."""
    available = size - file.tell()
    magic = file.read(min(8, max(available, 0)))
    if len(magic) < 8:
        raise _CutShort
    width = _VERSIONS.get((magic[6], magic[7])) if magic[:6] == b"\x93NUMPY" else None
    if width is None:
        raise ValueError("no .npy array there")
    length_bytes = file.read(min(width, available - 8))
    length = int.from_bytes(length_bytes, "little")
    if len(length_bytes) < width or available < 8 + width + length:
        raise _CutShort
    parse = np.lib.format.read_array_header_1_0 if width == 2 else np.lib.format.read_array_header_2_0
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # (numpy warns when it has to rewrite a header to read it: not ours)
            shape, fortran, dtype = parse(io.BytesIO(length_bytes + file.read(length)))
    except _HEADER_ERRORS as error:
        raise ValueError(f"a corrupted .npy header: {type(error).__name__}") from None
    if fortran or dtype.hasobject or any(n < 0 for n in shape):
        raise ValueError(f"not a C-ordered array of numbers or text: {dtype}, shape {shape}")
    count = math.prod(shape)
    if count * dtype.itemsize > available - 8 - width - length:
        raise _CutShort
    return np.fromfile(file, dtype=dtype, count=count).reshape(shape)


def _read_names(file: BinaryIO, size: int) -> list[str]:
    """The column names that start a trace file: ValueError (why it is not one) unless the first
    array is a 1-D array of distinct, non-empty, printable strings."""
    try:
        names = _read_array(file, size)
    except _CutShort:
        raise ValueError("it ends inside its first array") from None
    if (names.dtype.kind != "U" or names.ndim != 1 or not names.size
            or names.astype(names.dtype.newbyteorder("=")).view(np.uint32).max() > 0x10FFFF):  # (not text: not read)
        raise ValueError(f"its first array is not a list of column names: {names.dtype}, shape {names.shape}")
    text = [str(name) for name in names]
    if len(set(text)) < len(text) or not all(name and name.isprintable() for name in text):
        raise ValueError(f"its column names are not distinct printable names: {[name[:40] for name in text]!r:.200}")
    return text


def _read_chunk(file: BinaryIO, size: int, before: dict[str, list[np.ndarray]]) -> list[np.ndarray]:
    """The next chunk: one float array per column of ``before`` (the chunks read so far), with as
    many rows each, ``time`` 1-D and every other column the shape of its first chunk. ValueError
    if it is not one, :class:`_CutShort` if the data end inside it."""
    chunk = [_read_array(file, size) for _ in before]
    rows = chunk[0].shape[0] if chunk[0].ndim else 1
    for (name, earlier), values in zip(before.items(), chunk, strict=True):
        if values.dtype != np.float64 or values.ndim == 0 or values.shape[0] != rows:
            raise ValueError(f"column {name!r} is not {rows} rows of numbers: {values.dtype}, shape {values.shape}")
        if (name == "time" and values.ndim != 1) or (earlier and earlier[0].shape[1:] != values.shape[1:]):
            raise ValueError(f"column {name!r} changed shape: {values.shape}")
    return chunk


def trace_file_problem(path: Path) -> str | None:
    """Why the file at ``path`` is not a trace file (its column names and its first chunk, or the
    beginning of it, are checked), None when it is one or is empty."""
    size = path.stat().st_size
    if size == 0:
        return None
    with open(path, "rb") as file:
        try:
            names = _read_names(file, size)
            if file.tell() == size:
                return "it holds a list of names and no chunk"
            _read_chunk(file, size, {name: [] for name in names})
        except _CutShort:
            return None  # (a run stopped while writing its first chunk)
        except ValueError as error:
            return str(error)
    return None


def stream_path(path: Path, taken: Iterable[Path]) -> Path:
    """``path`` if a tracer may stream to it: a file in an existing folder, not one of ``taken`` (the
    other tracers' files), and either new, empty or a trace file already (a file of another kind is
    not overwritten: :func:`trace_file_problem`); else :class:`InvalidInput`, nothing written."""
    try:
        if path.is_dir() or not path.parent.is_dir():
            raise InvalidInput(f"tracer stream: {str(path)!r} is a folder or its folder does not exist: give a file path")
        if any(other.resolve() == path.resolve() for other in taken):
            raise InvalidInput(f"tracer stream: another tracer streams to {str(path)!r}")
        problem = trace_file_problem(path) if path.is_file() else None
        if problem is not None:
            raise InvalidInput(f"tracer stream: {str(path)!r} exists and is not a trace file ({problem}): not overwritten")
    except SotError:
        raise
    except (OSError, ValueError) as error:  # (a NUL byte in the path: ValueError)
        raise InvalidInput(f"tracer stream: {str(path)!r}: {os_reason(error)}") from None
    return path


def row_digest(values: Iterable[np.ndarray]) -> bytes:
    """A digest of one sample row (the time, then each signal's values): two rows with the same
    digest hold the same numbers."""
    digest = hashlib.blake2b(digest_size=16)
    for value in values:
        digest.update(np.ascontiguousarray(value, dtype=float).tobytes())
    return digest.digest()


def read_trace(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays of a chunk file a tracer streamed to (``time`` and each signal, concatenated; empty
    when the file was cut inside its first chunk, with a warning). A file that is not a trace file
    (a plain ``np.save`` file, a corrupted header: see the module docstring): :class:`InvalidInput`."""
    if not isinstance(path, str | Path):
        raise InvalidInput(f"read_trace: a file path, got {path!r:.60}")
    if Path(path).is_dir():
        raise InvalidInput(f"read_trace: {str(path)!r} is a folder, not a trace file")
    reader = ChunkFile(Path(path), existing=True)
    return {name: np.concatenate(parts) if parts else np.zeros((0,) if name == "time" else (0, 0))
            for name, parts in reader.read().items()}
