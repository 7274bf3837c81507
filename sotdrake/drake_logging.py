"""Drake's log messages (the Python logger ``drake``): quieter where a message says nothing useful."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator

_LOGGER = logging.getLogger("drake")


@contextlib.contextmanager
def drake_log_level(level: int) -> Iterator[None]:
    """Drake's log level set to ``level`` (e.g. ``logging.WARNING``) inside the block."""
    before = _LOGGER.level
    _LOGGER.setLevel(level)
    try:
        yield
    finally:
        _LOGGER.setLevel(before)


class _DropMessage(logging.Filter):
    def __init__(self, beginning: str):
        super().__init__()
        self.beginning = beginning

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith(self.beginning)


def drop_drake_message(beginning: str) -> None:
    """Never show Drake's messages that start with ``beginning`` (installed once per text)."""
    if not any(isinstance(f, _DropMessage) and f.beginning == beginning for f in _LOGGER.filters):
        _LOGGER.addFilter(_DropMessage(beginning))
