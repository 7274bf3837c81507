"""A live command's arguments and answers: the declared parameters (:class:`Param`) of an allowed
method (:class:`Method`), the checks of a number or a vector argument, a checked command
(:class:`Prepared`) and the text of its answer."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydrake.systems.framework import Context

from ..exceptions import CommandRejected
from .grammar import Command, EntityRef

REQUIRED = object()

#: Longest vector argument (numbers), e.g. a posture of a bigger robot.
MAX_VECTOR = 256


@dataclass(frozen=True)
class Param:
    """One argument: ``kind`` is one of the kinds :meth:`.Vocabulary.prepare` checks (``number``, ``numbers``,
    ``vector``, ``text``, ``task``, ``meta``, ``entity``, ``time``, ``command``); ``default`` makes it optional."""

    name: str
    kind: str
    default: Any = REQUIRED


@dataclass(frozen=True)
class Method:
    """An allowed method: ``apply(context, *values)`` returns the answer (``None``: ``'ok'``)."""

    params: tuple[Param, ...]
    apply: Callable[..., Any]
    doc: str = ""
    #: It reads and changes the context it is given only (``attime`` tries it on a copy first).
    context_only: bool = True
    #: It only answers a question (``attime`` refuses it: at T its answer would go nowhere).
    query: bool = False

    def signature(self, callee: str) -> str:
        shown = [p.name if p.default is REQUIRED else f"{p.name}={p.default!r}" for p in self.params]
        return f"{callee}({', '.join(shown)})"


@dataclass(frozen=True)
class Prepared:
    """A checked command, ready to be applied to a context at a tick boundary."""

    command: Command
    method: Method
    values: tuple

    def __call__(self, context: Context) -> str:
        answer = self.method.apply(context, *self.values)
        return "ok" if answer is None else answer if isinstance(answer, str) else answer_text(answer)

    def __str__(self) -> str:
        return str(self.command)


def answer_text(value) -> str:
    """An answer's text: arrays in full (to 6 digits), transforms as 4×4 matrices."""
    if hasattr(value, "GetAsMatrix4"):
        value = value.GetAsMatrix4()
    if isinstance(value, np.ndarray):
        return np.array2string(value, precision=6, suppress_small=True, max_line_width=200, threshold=100_000)
    return repr(value)


def number(value, what: str) -> float:
    """``value`` as a finite float, else :class:`CommandRejected` naming ``what``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CommandRejected(f"{what}: expected a number, got {describe(value)}")
    number = float(value)  # an int too large for a float raises OverflowError, caught below
    if not math.isfinite(number):
        raise CommandRejected(f"{what}: expected a finite number, got {value!r}")
    return number


def describe(value) -> str:
    """``value`` as a refusal names it (a name, a command, or its type and start)."""
    if isinstance(value, EntityRef):
        return f"the name {value.name}"
    if isinstance(value, Command):
        return f"the command {value}"
    return f"{type(value).__name__} {value!r:.40}"


def vector(value, what: str) -> np.ndarray:
    """A tuple of numbers (a vector) or of equal-length tuples (a matrix, row by row) as an array, at most
    :data:`MAX_VECTOR` numbers; else :class:`CommandRejected` naming ``what``."""
    if not isinstance(value, tuple):
        raise CommandRejected(f"{what}: expected a tuple of numbers such as (0.5, -0.2, 1.0), got {describe(value)}")

    def flat(v, depth=0):
        if isinstance(v, tuple) and depth < 2:
            for item in v:
                yield from flat(item, depth + 1)
        else:
            yield v

    numbers = [number(x, what) for x in flat(value)]
    if len(numbers) > MAX_VECTOR:
        raise CommandRejected(f"{what}: at most {MAX_VECTOR} numbers, got {len(numbers)}")
    rows = [len(r) if isinstance(r, tuple) else None for r in value]
    if all(r is None for r in rows):
        return np.array(numbers)
    lengths = [r for r in rows if r is not None]
    if len(lengths) != len(rows) or len(set(lengths)) != 1:
        raise CommandRejected(f"{what}: a matrix needs rows of equal length, got {value!r:.80}")
    return np.array(numbers).reshape(len(rows), lengths[0])
