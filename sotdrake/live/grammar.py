"""The grammar of a live command: one call in the SoT vocabulary, with literal arguments.

A command is one line such as ``sot.push('taskrh')``, ``gotoNd(taskRH, (0.5, -0.2, 1.0), '111',
(4.9, 0.9, 0.01, 0.9))``, ``taskRH.gain.setConstant(10)`` or ``attime(2.5, sot.pop())``. It is read
with :func:`ast.parse` and then walked on a whitelist; nothing is ever evaluated:

* the whole line is one call;
* the callee is a plain name (a function: ``gotoNd``) or a dotted path of at most three plain names
  (``entity.method``, ``entity.component.method``); the path is only a key looked up in the
  vocabulary's explicit tables, never an attribute access;
* an argument is a number (``int``/``float``, optionally with a unary ``-`` or ``+``), a string,
  ``True``/``False``/``None``, a tuple or list of arguments, a bare name (a reference to an entity,
  resolved by the vocabulary), or a nested call (a deferred command, for ``attime``);
* keyword arguments (``gain=3``) are allowed, ``*args``/``**kwargs`` are not;
* no name anywhere may start with ``_`` (no dunder);
* at most :data:`MAX_CHARACTERS` characters and :data:`MAX_NODES` syntax nodes.

Anything else (attribute access outside the callee, subscripts, operators, lambdas, comprehensions,
f-strings, bytes, complex numbers …) raises :class:`~sotdrake.exceptions.CommandRejected` naming what
was refused.
"""

from __future__ import annotations

import ast
import math
from dataclasses import dataclass, field

from ..exceptions import CommandRejected

#: Longest command accepted (characters).
MAX_CHARACTERS = 4096
#: Most syntax nodes in one command (the tutorial's ``gotoNd`` has 17).
MAX_NODES = 400
#: Deepest callee path: ``entity.component.method``.
MAX_PATH = 3



@dataclass(frozen=True)
class EntityRef:
    """A bare name in argument position (``taskRH`` in ``gotoNd(taskRH, …)``)."""

    name: str


@dataclass(frozen=True)
class Command:
    """``target.method(*args, **kwargs)``; ``target`` is ``''`` for a function (``gotoNd``)."""

    target: str
    method: str
    args: tuple = ()
    kwargs: tuple[tuple[str, object], ...] = field(default=())

    @property
    def callee(self) -> str:
        return f"{self.target}.{self.method}" if self.target else self.method

    def __str__(self) -> str:
        arguments = [_show(a) for a in self.args] + [f"{k}={_show(v)}" for k, v in self.kwargs]
        return f"{self.callee}({', '.join(arguments)})"


def _show(value) -> str:
    if isinstance(value, EntityRef):
        return value.name
    if isinstance(value, tuple):
        inner = ", ".join(_show(v) for v in value)
        return f"({inner},)" if len(value) == 1 else f"({inner})"
    return str(value) if isinstance(value, Command) else repr(value)


def parse_command(text: str) -> Command:
    """The :class:`Command` written in ``text``; raises ``CommandRejected`` for anything else."""
    if not isinstance(text, str):
        raise CommandRejected(f"a command is text, got {type(text).__name__}")
    text = text.strip()
    if not text:
        raise CommandRejected("empty command")
    if len(text) > MAX_CHARACTERS:
        raise CommandRejected(f"command too long: {len(text)} characters, at most {MAX_CHARACTERS}")
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as error:
        raise CommandRejected(f"not a command: {error.msg} (a command is a call such as sot.push('taskrh'))") from None
    except (RecursionError, MemoryError, ValueError) as error:  # absurd nesting, NUL bytes
        raise CommandRejected(f"not a command: {type(error).__name__}") from None
    nodes = sum(1 for _ in ast.walk(tree))
    if nodes > MAX_NODES:
        raise CommandRejected(f"command too complex: {nodes} syntax nodes, at most {MAX_NODES}")
    if not isinstance(tree.body, ast.Call):
        raise CommandRejected(
            f"a command is one call such as sot.push('taskrh'), got {_describe(tree.body)}"
        )
    return _call(tree.body)


def _call(node: ast.Call) -> Command:
    path = _callee(node.func)
    args = tuple(_argument(a) for a in node.args)
    kwargs = []
    for keyword in node.keywords:
        if keyword.arg is None:
            raise CommandRejected("'**' arguments are not allowed")
        _check_name(keyword.arg)
        kwargs.append((keyword.arg, _argument(keyword.value)))
    return Command(".".join(path[:-1]), path[-1], args, tuple(kwargs))


def _callee(node: ast.expr) -> list[str]:
    parts: list[str] = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        raise CommandRejected(f"the called thing must be a name such as sot.push, got {_describe(node)}")
    parts.append(node.id)
    parts.reverse()
    for part in parts:
        _check_name(part)
    if len(parts) > MAX_PATH:
        raise CommandRejected(f"{'.'.join(parts)}: at most {MAX_PATH} names (entity.component.method)")
    return parts


def _check_name(name: str) -> None:
    if name.startswith("_"):
        raise CommandRejected(f"names starting with '_' are not allowed: {name!r}")
    if not name.isidentifier() or not name.isascii():
        raise CommandRejected(f"not a plain name: {name!r}")


def _argument(node: ast.expr):
    if isinstance(node, ast.Constant):
        value = node.value
        if value is None or isinstance(value, (bool, int, str)):
            return value
        if isinstance(value, float):
            if not math.isfinite(value):
                raise CommandRejected(f"numbers must be finite, got {value}")
            return value
        raise CommandRejected(f"literal of type {type(value).__name__} is not allowed: {value!r:.40}")
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        operand = node.operand
        if isinstance(operand, ast.Constant) and isinstance(operand.value, (int, float)) and not isinstance(operand.value, bool):
            value = operand.value
            return -value if isinstance(node.op, ast.USub) else value
        raise CommandRejected("a sign applies to a number only")
    if isinstance(node, (ast.Tuple, ast.List)):
        return tuple(_argument(e) for e in node.elts)
    if isinstance(node, ast.Name):
        _check_name(node.id)
        return EntityRef(node.id)
    if isinstance(node, ast.Call):
        return _call(node)
    raise CommandRejected(f"argument not allowed: {_describe(node)} (numbers, strings, tuples, entity names)")


def _describe(node: ast.AST) -> str:
    try:
        text = ast.unparse(node)
    except Exception:  # pragma: no cover - unparse handles every parsed node
        text = ""
    text = text if len(text) <= 60 else text[:57] + "..."
    return f"{type(node).__name__.lower()} {text!r}"
