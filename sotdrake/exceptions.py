"""Exceptions raised by sotdrake.

Every error is raised at construction (or at the command that caused it) with a message that
names what was asked for and what exists, never deep inside a simulation callback when avoidable.
"""

from __future__ import annotations

from collections.abc import Iterable


class SotError(Exception):
    """Base class of every sotdrake error."""


class InvalidInput(SotError, ValueError):
    """A value has the wrong size, is not finite, or is out of its domain."""


class NotFound(SotError, KeyError):
    """A name (frame, task, robot variant, package) does not exist.

    The message lists the names that do exist, so that a typo is obvious.
    """

    kind = "name"

    def __init__(self, name: str, available: Iterable[str]):
        import difflib

        self.name = name
        # A list keeps its order (most useful names first); any other iterable is sorted.
        self.available = list(available) if isinstance(available, (list, tuple)) else sorted(available)
        close = difflib.get_close_matches(str(name), self.available, n=3)
        hint = f" (did you mean {', '.join(map(repr, close))}?)" if close else ""
        shown = ", ".join(repr(a) for a in self.available[:40])
        more = f" … and {len(self.available) - 40} more" if len(self.available) > 40 else ""
        super().__init__(f"unknown {self.kind} {name!r}{hint}; available: {shown}{more}")

    def __str__(self) -> str:  # KeyError would quote the whole message otherwise
        return str(self.args[0])


class FrameNotFound(NotFound):
    kind = "frame or operational point"


class TaskNotFound(NotFound):
    kind = "task"


class RobotNotFound(NotFound):
    kind = "robot variant"


class StackError(SotError):
    """A stack command that cannot be applied (duplicate push, pop of an empty stack …).

    The stack is left unchanged.
    """


class CommandRejected(InvalidInput):
    """A live command the grammar or the allow-list refuses (not a call, a name that is not
    offered, an argument of the wrong kind). Nothing is applied."""


class SolverError(SotError):
    """The solver met a non-finite Jacobian or reference; the message names the task."""


def check_finite(name: str, value, shape: tuple[int, ...] | None = None):
    """Return ``value`` as a float array after checking its shape and finiteness."""
    import numpy as np

    array = np.asarray(value, dtype=float)
    if shape is not None and array.shape != shape:
        raise InvalidInput(f"{name}: expected shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InvalidInput(f"{name}: contains NaN or infinity: {array}")
    return array
