"""The footstep planner: where and when each foot lands.

The walking frame ``B = (x, y, yaw)`` (world, on the ground) is the mid-point of the feet; a foot
at rest in it sits at ``B ⊕ (0, ±d/2)`` (left +, right −, ``d`` the feet distance). A step moves
``B`` by a displacement ``(dx, dy, dθ)`` expressed in ``B``: ``yaw ← yaw + dθ``, and the
translation ``(dx, dy)`` is rotated by the mid-step yaw ``yaw + dθ/2``; the swinging foot lands at
its rest place in the new ``B``. Steps alternate feet. The velocity command ``(vx, vy, ω)`` gives,
per step of duration ``T``, ``(vx T, vy' , ω T)`` with the lateral motion done by the foot that
leads it (left for ``vy > 0``): ``vy' = 2 vy T`` on its steps and 0 on the other's, so that the
feet never close in on each other; the mean velocity is the command's.

Timing: lift-off ``t_k``, touch-down ``t_k + T_ss``, next lift-off ``t_k + T`` (see
:class:`GaitParameters`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InvalidInput, check_finite, check_type, finite_number
from .gait import GaitParameters

SIDES = ("left", "right")


@dataclass(frozen=True)
class Footstep:
    """One step: ``side`` swings from ``liftoff`` to ``touchdown`` (s) and lands at ``(x, y, yaw)``
    (its sole frame's origin and yaw, world); ``body`` is the walking frame after the step."""

    side: str
    liftoff: float
    touchdown: float
    x: float
    y: float
    yaw: float
    body: tuple[float, float, float]

    @property
    def position(self) -> np.ndarray:
        return np.array([self.x, self.y])


def other(side: str) -> str:
    return "right" if side == "left" else "left"


def rest_place(body, side: str, feet_distance: float) -> tuple[float, float, float]:
    """``B ⊕ (0, ±d/2)``: the sole pose ``(x, y, yaw)`` of ``side`` at rest in the walking frame ``B``."""
    x, y, yaw = body
    offset = feet_distance / 2 if side == "left" else -feet_distance / 2
    return (x - np.sin(yaw) * offset, y + np.cos(yaw) * offset, yaw)


def move(body, displacement) -> tuple[float, float, float]:
    """``B`` moved by ``(dx, dy, dθ)`` expressed in ``B`` (translation along the mid-step yaw)."""
    x, y, yaw = body
    dx, dy, dtheta = displacement
    heading = yaw + dtheta / 2
    c, s = np.cos(heading), np.sin(heading)
    return (x + c * dx - s * dy, y + s * dx + c * dy, yaw + dtheta)


def first_side(velocity) -> str:
    """The foot that steps first: the one on the side of the lateral motion, else of the turn,
    else the right foot."""
    vx, vy, w = velocity
    if vy or w:
        return "left" if (vy if vy else w) > 0 else "right"
    return "right"


def velocity_displacement(velocity, side: str, gait: GaitParameters) -> tuple[float, float, float]:
    """The walking frame's displacement during one step of ``side`` under ``velocity``."""
    vx, vy, w = velocity
    T = gait.step_duration
    leads = vy != 0 and (side == "left") == (vy > 0)
    return (vx * T, 2 * vy * T if leads else 0.0, w * T)


def plan_steps(body, side: str, liftoff: float, displacements, gait: GaitParameters) -> list[Footstep]:
    """Steps from the walking frame ``body`` (finite ``(x, y, yaw)``): the first by ``side``
    (``'left'`` or ``'right'``) lifting off at ``liftoff`` (s, finite), one per displacement
    (finite ``(dx, dy, dθ)``; feet alternating). Anything else: :class:`InvalidInput` naming it."""
    body = tuple(check_finite("plan_steps: body (x, y, yaw)", body, (3,)))
    if side not in SIDES:
        raise InvalidInput(f"plan_steps: side must be 'left' or 'right', got {side!r:.60}")
    if not finite_number(liftoff):
        raise InvalidInput(f"plan_steps: liftoff must be a finite number (s), got {liftoff!r:.60}")
    array = check_finite("plan_steps: displacements", displacements)
    if array.size and (array.ndim != 2 or array.shape[1] != 3):
        raise InvalidInput(f"plan_steps: displacements must be a list of (dx, dy, dθ), got shape {array.shape}")
    check_type("plan_steps: gait", gait, GaitParameters, "GaitParameters")
    return steps_from(body, side, liftoff, displacements, gait)


def steps_from(body, side: str, liftoff: float, displacements, gait: GaitParameters) -> list[Footstep]:
    """:func:`plan_steps` for arguments already checked (the walk plans' own)."""
    steps = []
    for displacement in displacements:
        body = move(body, displacement)
        x, y, yaw = rest_place(body, side, gait.feet_distance)
        steps.append(Footstep(side, liftoff, liftoff + gait.single_support, x, y, yaw, body))
        side, liftoff = other(side), liftoff + gait.step_duration
    return steps


def closing_steps(body, side: str, liftoff: float, feet: dict, gait: GaitParameters, tolerance: float = 1e-6) -> list[Footstep]:
    """Steps that bring the feet (``feet[side] = (x, y, yaw)``) to their rest places in ``body``,
    ``side`` first: none for a foot already there."""
    steps = []
    for s in (side, other(side)):
        target = rest_place(body, s, gait.feet_distance)
        if np.abs(np.subtract(target, feet[s])).max() > tolerance:
            steps.append(Footstep(s, liftoff, liftoff + gait.single_support, *target, tuple(body)))
            liftoff += gait.step_duration
    return steps
