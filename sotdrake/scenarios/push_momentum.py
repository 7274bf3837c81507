"""The largest torso push the dynamic SoT survives, without and with angular-momentum damping.

The ``push`` scenario of ``diagrams/talos_dynamics.py`` on the physics device (TALOS under torque
control, ``SolverDyn``: both soles held, the soft CoM task, the posture), with one push on the torso
(``torso_2_link``, +x) of ``--push-duration`` seconds starting at ``--push-start``. For each setting
(no momentum task; ``MetaTaskDynMomentum`` with ``K_v = --damping`` in its own level under the CoM
task, or with ``--weight W`` in one weighted level with the posture, posture 1 and momentum W), a
bisection on the push's force between ``--forces LOW,HIGH`` (N) finds the largest push survived to
``(HIGH − LOW)/2^steps``. A run has fallen when the base drops by more than 0.25 m or tilts by more
than 30° from upright (or the state is not finite); it stops there::

    python diagrams/push_momentum.py --damping 10 --forces 100,900 --steps 4 --out out/push_momentum

writes ``DIR/summary.json`` (each setting's largest force survived, the smallest that felled TALOS,
and every run's outcome). The options are checked before the first run: ``0 ≤ LOW < HIGH ≤
10,000 N`` (``sotdrake.physics.MAX_PUSH_FORCE``) and a push that ends within the run
(``--push-start`` + ``--push-duration`` ≤ ``--duration``).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys

import numpy as np
from pydrake.systems.analysis import Simulator

from sotdrake import MAX_DURATION, json_safe, script_arguments, start
from sotdrake.scenarios import talos_dynamics
from sotdrake.scenarios.push_map import MAX_PUSH_FORCE

FALL_DROP_M = 0.25  # the base below its start by this much: fallen (as talos_dynamics.py says)
FALL_TILT_DEG = 30.0  # or the base tilted this far from upright (as push_map.py says)
CHECK_PERIOD_S = 0.02  # how often a run looks whether TALOS has fallen


def survives(force: float, damping: float | None, push_start: float, push_duration: float, duration: float,
             weight: float | None = None) -> dict:
    """One push run, stopped as soon as TALOS has fallen: the base dropped more than
    ``FALL_DROP_M`` or tilted more than ``FALL_TILT_DEG`` from upright, or the state is not finite."""
    run = talos_dynamics.build_diagram("push", "physics", momentum_damping=damping,
                                       pushes=((push_start, push_duration, [force, 0.0, 0.0]),), momentum_weight=weight)
    simulator = Simulator(run.diagram)
    simulator.Initialize()
    port = run.robot.state_port
    nq = run.robot.model.nq
    z0, t, fell = None, 0.0, False
    while t < duration - 1e-9 and not fell:
        t = min(duration, t + CHECK_PERIOD_S)
        simulator.AdvanceTo(t)
        q = port.Eval(port.get_system().GetMyContextFromRoot(simulator.get_context()))[:nq]
        z0 = q[6] if z0 is None else z0
        tilt = np.degrees(np.arccos(np.clip(1.0 - 2.0 * (q[1] ** 2 + q[2] ** 2), -1.0, 1.0)))  # base z axis from vertical
        fell = bool(not np.isfinite(q).all() or z0 - q[6] > FALL_DROP_M or tilt > FALL_TILT_DEG)
    return {"force_n": force, "fell": fell, "until_s": t}


def largest_push(damping: float | None, low: float, high: float, steps: int, args) -> dict:
    """Bisection between ``low`` (survived) and ``high`` (fell), each checked first."""
    runs = []

    def attempt(force: float) -> bool:
        outcome = survives(force, damping, args.push_start, args.push_duration, args.duration,
                           args.weight if damping is not None else None)
        runs.append(outcome)
        print(f"damping {damping}: {force:.1f} N: {'fell' if outcome['fell'] else 'survived'}", file=sys.stderr, flush=True)
        return not outcome["fell"]

    if not attempt(low):
        return {"damping_kv": damping, "survived_n": None, "fell_n": low, "runs": runs}
    if attempt(high):
        return {"damping_kv": damping, "survived_n": high, "fell_n": None, "runs": runs}
    for _ in range(steps):
        middle = (low + high) / 2
        if attempt(middle):
            low = middle
        else:
            high = middle
    return {"damping_kv": damping, "survived_n": low, "fell_n": high, "runs": runs}


def _bracket(text: str) -> tuple[float, float]:
    """``LOW,HIGH`` (N): two finite numbers (an argparse type: a bad one names ``--forces``)."""
    try:
        low, high = (float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LOW,HIGH (two numbers, N), got {text!r}") from None
    if not (math.isfinite(low) and math.isfinite(high)):
        raise argparse.ArgumentTypeError(f"expected LOW,HIGH (two finite numbers, N), got {text!r}")
    return low, high


def check_options(args: argparse.Namespace) -> None:
    """A ``SystemExit`` naming the first option of ``args`` refused (:func:`~sotdrake.run_script`
    ends the script with it), before anything runs or is written."""
    low, high = args.forces
    if not (math.isfinite(args.damping) and args.damping >= 0) or (args.weight is not None and not args.weight > 0):
        raise SystemExit(f"--damping must be a finite number ≥ 0 and --weight > 0, got {args.damping}, {args.weight}")
    if not 0 <= low < high <= MAX_PUSH_FORCE or args.steps < 0:
        raise SystemExit(f"--forces must be LOW,HIGH with 0 ≤ LOW < HIGH ≤ {MAX_PUSH_FORCE:g} N and --steps ≥ 0, "
                         f"got {args.forces}, {args.steps}")
    if not 0 < args.duration <= MAX_DURATION:
        raise SystemExit(f"--duration must be a number in (0, {MAX_DURATION:g}] s, got {args.duration}")
    if not (math.isfinite(args.push_start) and math.isfinite(args.push_duration)):
        raise SystemExit(f"--push-start and --push-duration must be finite, got {args.push_start}, {args.push_duration}")
    if not (0 <= args.push_start and args.push_duration > 0 and args.push_start + args.push_duration <= args.duration + 1e-9):
        raise SystemExit(f"--push-start {args.push_start:g} s and --push-duration {args.push_duration:g} s: the push must start "
                         f"at 0 s or later and end within the run (--duration {args.duration:g} s)")


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/push_momentum", duration=2.5, bag=False, meshcat=False)
    parser.add_argument("--damping", type=float, default=10.0, help="K_v of the angular-momentum damping task (1/s)")
    parser.add_argument("--forces", type=_bracket, default=(100.0, 900.0), help="LOW,HIGH: the bisection's bracket (N)")
    parser.add_argument("--steps", type=int, default=4, help="bisection steps")
    parser.add_argument("--weight", type=float, default=None,
                        help="put the momentum task in one weighted level with the posture (posture 1, momentum WEIGHT) "
                             "instead of its own level under the CoM task")
    parser.add_argument("--push-start", type=float, default=0.5, help="s")
    parser.add_argument("--push-duration", type=float, default=0.1, help="s")
    args = parser.parse_args(argv)
    check_options(args)
    start(args)  # (no recording: many runs, numbers only)
    logging.getLogger("drake").setLevel(logging.WARNING)
    low, high = args.forces
    summary = {"momentum_level": "strict, under the CoM task" if args.weight is None else f"weighted with the posture, w = {args.weight:g}",
               "push": {"start_s": args.push_start, "duration_s": args.push_duration, "body": "torso_2_link", "direction": "+x"},
               "duration_s": args.duration,
               "without": largest_push(None, low, high, args.steps, args),
               "with": largest_push(args.damping, low, high, args.steps, args)}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "summary.json").write_text(json.dumps(json_safe(summary), indent=2) + "\n")
    return summary
