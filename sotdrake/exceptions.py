"""Exceptions raised by sotdrake.

Every error is raised at construction (or at the command that caused it) with a message that
names what was asked for and what exists, never deep inside a simulation callback when avoidable.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import TypeVar

T = TypeVar("T")


class SotError(Exception):
    """Base class of every sotdrake error."""


class SotWarning(UserWarning):
    """Something that works but may not do what was meant (a command that does not reach a running
    simulation, a task that constrains nothing, a target that is not reached)."""


class InvalidInput(SotError, ValueError):
    """A value has the wrong size, is not finite, or is out of its domain."""


#: Words a user may type for an op point, and the words the op-point names use instead.
_SYNONYMS: dict[str, tuple[str, ...]] = {
    "hand": ("wrist", "gripper", "tool"),
    "gripper": ("wrist", "tool", "hand"),
    "tool": ("wrist", "gripper", "hand"),
    "effector": ("tool", "wrist"),
    "foot": ("ankle", "sole"),
    "leg": ("ankle",),
    "head": ("gaze",),
    "camera": ("gaze",),
    "torso": ("chest",),
    "trunk": ("chest",),
    "pelvis": ("waist",),
    "base": ("waist",),
}


def _normalised(name: str) -> str:
    return re.sub(r"[-_\s.]+", "_", name.strip().lower())


def close_matches(name: str, available: Iterable[str], n: int = 3) -> list[str]:
    """Up to ``n`` names of ``available`` close to ``name``: the same name up to case and
    ``-``/``_``/space, then the name with one word replaced by a synonym (``right_hand`` →
    ``right-wrist``), then :func:`difflib.get_close_matches` on the normalised names."""
    import difflib

    normalised: dict[str, str] = {}
    for candidate in available:
        normalised.setdefault(_normalised(str(candidate)), str(candidate))
    key = _normalised(name)
    found = [normalised[key]] if key in normalised else []
    words = key.split("_")
    for i, word in enumerate(words):
        for synonym in _SYNONYMS.get(word, ()):
            replaced = "_".join([*words[:i], synonym, *words[i + 1 :]])
            if replaced in normalised:
                found.append(normalised[replaced])
    found += [normalised[c] for c in difflib.get_close_matches(key, list(normalised), n=n)]
    return list(dict.fromkeys(found))[:n]


class NotFound(SotError, KeyError):
    """A name (frame, task, robot variant, package) does not exist.

    The message lists the names that do exist, so that a typo is obvious.
    """

    kind = "name"

    def __init__(self, name: str, available: Iterable[str]):
        self.name = name
        # A list keeps its order (most useful names first); any other iterable is sorted.
        self.available = list(available) if isinstance(available, (list, tuple)) else sorted(available)
        close = close_matches(str(name), self.available)
        hint = f" (did you mean {', '.join(map(repr, close))}?)" if close else ""
        shown = ", ".join(repr(a) for a in self.available[:40])
        more = f" … and {len(self.available) - 40} more" if len(self.available) > 40 else ""
        super().__init__(f"unknown {self.kind} {name!r}{hint}; available: {shown}{more}")

    def __str__(self) -> str:  # KeyError would quote the whole message otherwise
        return str(self.args[0])

    def but(self, reason: str) -> NotFound:
        """This error with ``reason`` in front of its message (e.g. what kind of value was expected)."""
        self.args = (f"{reason}: {self.args[0]}",)
        return self


class FrameNotFound(NotFound):
    """A frame, joint or operational point the robot model does not have; lists those it has."""

    kind = "frame or operational point"


class TaskNotFound(NotFound):
    """A task name the solver does not know; lists the tasks it knows."""

    kind = "task"


class RobotNotFound(NotFound):
    """A robot name that is neither in the catalog nor the path of a file; lists the catalog."""

    kind = "robot"


class VariantNotFound(RobotNotFound):
    kind = "robot variant"


class RobotFileNotFound(RobotNotFound):
    """A robot description file (URDF, SDF, MJCF) given by path does not exist."""

    def __init__(self, path: str, available: Iterable[str]):
        self.name, self.available = path, list(available)
        shown = ", ".join(repr(a) for a in self.available)
        Exception.__init__(self, f"robot file {path!r} not found; give the path of an existing URDF, SDF or MJCF "
                                 f"file, or the name of a robot of the catalog: {shown}")


class PackageNotFound(NotFound):
    """A ``package://<name>/…`` URI of a robot description names a package that was not found."""

    kind = "package"

    def __init__(self, name: str, available: Iterable[str], uri: str = ""):
        super().__init__(name, available)
        where = f" (in {uri!r})" if uri else ""
        self.args = (f"{self.args[0]}{where}; give its folder: load_robot(..., package_paths={{{name!r}: "
                     f"'/path/to/{name}'}}) or put a package.xml in it",)


class OperationalPointNotFound(FrameNotFound):
    """An op-point name not in ``robot.OperationalPointsMap`` (a ``KeyError``)."""

    kind = "operational point"


class StackError(SotError):
    """A stack command that cannot be applied (duplicate push, pop of an empty stack …).

    The stack is left unchanged.
    """


class RobotDescriptionError(SotError, ValueError):
    """A robot description (URDF) Drake would reject or abort on; the message names the joint."""


class CommandRejected(InvalidInput):
    """A live command the grammar or the allow-list refuses (not a call, a name that is not
    offered, an argument of the wrong kind). Nothing is applied."""


class SolverError(SotError):
    """The solver met a non-finite Jacobian or reference; the message names the task."""


def os_reason(error: BaseException) -> str:
    """What an ``OSError`` says went wrong (its ``strerror``, e.g. "Permission denied"), or the
    error itself when it has no such text."""
    return str(getattr(error, "strerror", None) or error)


def all_numbers(value) -> bool:
    """True if ``value`` is a real number or nested sequences/arrays of them (no str, bool, None)."""
    import numbers

    import numpy as np

    if isinstance(value, np.ndarray):
        return value.dtype.kind in "iuf" or (value.dtype.kind == "O" and all(all_numbers(v) for v in value.ravel()))
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, numbers.Integral):  # (a Python int beyond a float's range is not one of ours)
        return abs(int(value)) < 2**1024
    if isinstance(value, numbers.Real):
        return True
    if isinstance(value, (list, tuple)):
        return all(all_numbers(v) for v in value)
    return False


def finite_number(value) -> bool:
    """True if ``value`` is one finite real number (not a bool, an array or an int beyond a float's range)."""
    import math

    import numpy as np

    return all_numbers(value) and not np.ndim(value) and math.isfinite(value)


def check_name(what: str, name: object) -> str:
    """``name`` if it is a non-empty string (an entity's, a task's, an op point's), else
    :class:`InvalidInput`: "``what`` must be a non-empty string"."""
    if not isinstance(name, str) or not name:
        raise InvalidInput(f"{what} must be a non-empty string, got {name!r:.60}")
    return name


def check_type(what: str, value: T, kind: type | tuple[type, ...], expected: str) -> T:
    """``value`` if it is an instance of ``kind``, else :class:`InvalidInput`: "``what``: expected
    ``expected``, got <its type>"."""
    if not isinstance(value, kind):
        raise InvalidInput(f"{what}: expected {expected}, got {type(value).__name__}")
    return value


def check_flag(what: str, value: object) -> bool:
    """``value`` as a bool if it is one (a Python or numpy bool), else :class:`InvalidInput`: a
    flag given as a string or a number is a mistake (``"no"`` is true)."""
    import numpy as np

    if not isinstance(value, (bool, np.bool_)):
        raise InvalidInput(f"{what}: expected True or False, got {value!r:.60}")
    return bool(value)


#: The largest count :func:`check_count` takes by default (velocities, rows of a feature).
MAX_COUNT = 100_000


def check_count(name: str, value, low: int = 1, high: int = MAX_COUNT) -> int:
    """``value`` as an int if it is an integer (not a bool) in ``[low, high]``, else InvalidInput."""
    import numbers

    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not low <= int(value) <= high:
        raise InvalidInput(f"{name} must be an integer in [{low}, {high}], got {value!r:.100}")
    return int(value)


def check_number(name: str, value, low: float, high: float, unit: str = "") -> float:
    """``value`` as a float if it is a real number (not a bool) in ``[low, high]``, else InvalidInput."""
    if not all_numbers(value) or isinstance(value, (list, tuple)) or getattr(value, "ndim", 0) != 0:
        raise InvalidInput(f"{name} must be a number in [{low:g}, {high:g}]{unit}, got {value!r:.100}")
    number = float(value)
    if not low <= number <= high:  # NaN fails too
        raise InvalidInput(f"{name} must be a number in [{low:g}, {high:g}]{unit}, got {value!r:.100}")
    return number


def check_finite(name: str, value, shape: tuple[int, ...] | None = None, bound: float | None = None):
    """Return ``value`` as a float array after checking its shape, finiteness and, with ``bound``,
    ``|value| ≤ bound`` element-wise; anything else raises :class:`InvalidInput` naming ``name``."""
    import numpy as np

    expected = f"{'' if shape is None else f'shape {shape}, '}finite numbers" + (
        "" if bound is None else f" in [-{bound:g}, {bound:g}]")
    try:
        if not all_numbers(value):
            raise TypeError("not numbers")
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInput(f"{name}: expected {expected}, got {value!r:.200}") from None
    if shape is not None and array.shape != shape:
        raise InvalidInput(f"{name}: expected {expected}, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InvalidInput(f"{name}: expected {expected}; contains NaN or infinity: {array}")
    if bound is not None and array.size and np.abs(array).max() > bound:
        raise InvalidInput(f"{name}: expected {expected}, got {np.abs(array).max():g} in absolute value")
    return array
