"""Checks that a file can be written before a long or irreversible step, and the refusal of a
write that fails: :class:`~sotdrake.exceptions.InvalidInput` naming what writes, the path and the
operating system's reason."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from .exceptions import InvalidInput, SotError, os_reason


def check_writable(what: str, path: str | os.PathLike) -> Path:
    """``path`` as a ``Path`` if a file can be written there (opened to append, so an existing
    file is left as it is; a file this check creates is removed; a FIFO or a socket is refused),
    else :class:`InvalidInput` naming ``what``, the path and the reason."""
    if not isinstance(path, str | os.PathLike):
        raise InvalidInput(f"{what}: expected a file path, got {path!r:.60}")
    target = Path(path).expanduser()
    try:
        if target.is_dir():
            raise InvalidInput(f"{what}: {str(target)!r:.100} is a folder: give a file path")
        if target.is_fifo() or target.is_socket():  # (opening a FIFO waits for a reader: forever, for a script)
            raise InvalidInput(f"{what}: cannot write {str(target)!r:.100}: a FIFO or a socket (give a file path)")
        existed = target.exists()
        with open(target, "ab"):
            pass
        if not existed:
            target.unlink()
    except SotError:
        raise
    except (OSError, ValueError) as error:  # (a NUL byte in the path: ValueError)
        raise InvalidInput(f"{what}: cannot write {str(target)!r:.100}: {os_reason(error)}") from None
    return target


@contextmanager
def writing(what: str, path: Path) -> Iterator[None]:
    """``with writing(what, path):`` turns an ``OSError`` (or a path ``ValueError``) of the block
    into :class:`InvalidInput` naming ``what``, the path and the reason."""
    try:
        yield
    except SotError:
        raise
    except (OSError, ValueError) as error:
        raise InvalidInput(f"{what}: cannot write {str(path)!r:.100}: {os_reason(error)}") from None
