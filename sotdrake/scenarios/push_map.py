"""Push-recovery map: TALOS standing on a discrete ``MultibodyPlant`` with ground contact, pushed
on the torso over a grid of magnitude × direction × duration, under the kinematic controller (the
SoT on PD actuators) or the dynamic one (``SolverDyn``'s torques); writes ``push_map.csv`` (and
``.parquet``), ``push_map.json``, ``plots.png``, ``control_graph.svg`` and ``summary.json`` in
``--out``.

The controllers:

* ``--controller kinematic`` (default): the physics stand scenario (``diagrams/talos_physics.py
  --scenario stand``: the SoT holds feet and CoM, PD actuators track its references, open loop);
* ``--controller dynamic``: ``SolverDyn``'s torques (``diagrams/talos_dynamics.py --scenario push``
  with the case's push instead of the scenario's two).

Each case: the push (``torso_2_link``'s origin, horizontal, N) starts at ``--push-start``
(default 0.3 s) and lasts the case's duration; the run lasts ``--duration`` seconds (default 3 s,
1 ms steps: a push that tips TALOS may take more than 2 s to floor it). Direction 0° pushes along
+x (forward), 90° along +y (to the robot's left). A case *falls* by the criterion every script
shares (:mod:`sotdrake.fall`: the base tilted more than 30° or dropped more than 0.25 m, a held
sole slid more than 5 cm, another body on the ground); its base displacement is the largest
horizontal distance of the base from its start (m). Every link collides with the ground (a box
per link), so a fallen TALOS lands on it.

The options are checked, ``--out`` included, before any case runs: a push of more than 10,000 N
(``sotdrake.physics.MAX_PUSH_FORCE``), a push that does not end within the run (``--push-start`` +
the longest of ``--push-durations`` > ``--duration``: its impulse would not be the one reported),
a run of more than a day and a grid of more than 100,000 cases are refused. When every case fails,
the tables and the summary (its ``errors``) are written and the plot is left out.

    python diagrams/push_map.py --magnitudes 150,300,600 --directions 4 --push-durations 0.1,0.3 \\
        --engine ray --out out/push_map

writes ``push_map.csv`` (and ``.parquet`` with pyarrow), ``push_map.json``, ``plots.png`` (one
polar map per push duration: direction × magnitude, fall or not, base displacement),
``control_graph.svg`` and ``summary.json`` in the output directory.
"""

from __future__ import annotations

import argparse
from functools import partial
from pathlib import Path

import numpy as np

from sotdrake import MAX_DURATION, InvalidInput, fall_thresholds, save_figure, script_arguments, simulate, start, write_run
from sotdrake.scenarios import talos_dynamics, talos_physics
from sotdrake.sweep import EngineUnavailable, add_sweep_arguments, engine_options, grid, run_sweep

TIMING = ("wall_s", "realtime_factor")
#: The largest push (N) the physics takes (``sotdrake.physics.MAX_PUSH_FORCE``: ten times TALOS' weight).
MAX_PUSH_FORCE = 1e4
#: The most cases a map takes (magnitudes × directions × durations).
MAX_CASES = 100_000


def push_force(magnitude: float, direction_deg: float) -> np.ndarray:
    """The horizontal force (N, world): ``magnitude`` along ``(cos θ, sin θ, 0)``."""
    angle = np.radians(direction_deg)
    return magnitude * np.array([np.cos(angle), np.sin(angle), 0.0])


def push_case(case: dict, duration: float = 3.0, push_start: float = 0.3, controller: str = "kinematic") -> dict:
    """The sweep's case function: ``case = {'magnitude_n', 'direction_deg', 'push_duration_s'}``
    → the scenario's summary (with the shared fall criterion's ``fell``) and the push's impulse.
    ``controller``: ``kinematic`` (the SoT on PD actuators, ``talos_physics.py --scenario stand``)
    or ``dynamic`` (``SolverDyn`` torques, ``talos_dynamics.py --scenario push`` with this push)."""
    magnitude, push_duration = case["magnitude_n"], case["push_duration_s"]
    if not magnitude >= 0 or not push_duration > 0:
        raise InvalidInput(f"magnitude_n ≥ 0 and push_duration_s > 0, got {magnitude}, {push_duration}")
    force = push_force(magnitude, case["direction_deg"])
    if controller == "dynamic":
        run = talos_dynamics.build_diagram("push", "physics", pushes=((push_start, push_duration, force),))
        simulator, times = talos_dynamics.simulate_ticks(run, duration, progress=False)
        summary, _ = talos_dynamics.summarize(run, simulator, times, duration)
        summary["base_drift_m"] = _base_drift(run, simulator)
    else:
        stand = talos_physics.build_diagram("stand", "open", force, push_start=push_start, push_duration=push_duration)
        simulator, wall = simulate(stand.diagram, duration, None, progress=False)
        summary, _ = talos_physics.summarize(stand, simulator, duration, wall)
    for key in TIMING + ("hand_error_m", "hand_initial_error_m", "scenario", "tick_us_median", "tick_us_p95"):
        summary.pop(key, None)
    summary["controller"] = controller
    summary["impulse_ns"] = magnitude * push_duration
    return summary


def _base_drift(run, simulator) -> float:
    """The largest horizontal distance (m) of the base from its start, from the dynamic run's trace."""
    x = run.tracer.data(simulator.get_context())["x"]
    return float(np.nanmax(np.linalg.norm(x[:, 4:6] - x[0, 4:6], axis=1)))


def numbers(text: str) -> list[float]:
    """Comma-separated finite numbers > 0 (an argparse type: a bad one names its option)."""
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        values = []
    if not values or not all(np.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected comma-separated finite numbers > 0, got {text!r}")
    return values


def plot(rows: list[dict], path: Path, controller: str = "kinematic") -> Path | None:
    """One polar map per push duration: angle = push direction, radius = magnitude; colour = base
    displacement, a red cross where TALOS fell; None (nothing written) when no case ran."""
    if not any(r["status"] == "ok" for r in rows):
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r["status"] == "ok"]
    durations = sorted({r["push_duration_s"] for r in ok})
    top = max((r["base_drift_m"] for r in ok), default=0.1)
    fig, axes = plt.subplots(1, len(durations), subplot_kw={"projection": "polar"},
                             figsize=(4.4 * len(durations) + 1.2, 4.8), squeeze=False)
    for axis, duration in zip(axes[0], durations, strict=False):
        here = [r for r in ok if r["push_duration_s"] == duration]
        theta = np.radians([r["direction_deg"] for r in here])
        radius = np.array([r["magnitude_n"] for r in here])
        drift = np.array([r["base_drift_m"] for r in here])
        fell = np.array([r["fell"] for r in here])
        dots = axis.scatter(theta, radius, c=np.minimum(drift, top), cmap="viridis", vmin=0, vmax=top, s=160)
        axis.scatter(theta[fell], radius[fell], marker="x", c="r", s=120, linewidths=2.5)
        axis.set_title(f"push {duration:g} s", fontsize=10)
        axis.set_rlim(0, 1.15 * max(radius.max(), 1))
        axis.set_theta_zero_location("N")  # forward (+x) up, left (+y) to the left
    fig.colorbar(dots, ax=axes[0].tolist(), label="largest base displacement (m)")
    how = "SoT open loop, PD actuators" if controller == "kinematic" else "SolverDyn torques"
    fig.suptitle(f"TALOS standing ({how}): torso pushes; radius: force (N); red ×: fell")
    return save_figure(fig, path, tight=False)


def check_options(args: argparse.Namespace) -> tuple[list[dict], dict]:
    """The cases and the engine's options of ``args`` once every option is checked: a
    ``SystemExit`` naming the first one refused (:func:`~sotdrake.run_script` ends the script with
    it), before anything is written."""
    if not (np.isfinite(args.duration) and 0 < args.duration <= MAX_DURATION):
        raise SystemExit(f"--duration must be a number in (0, {MAX_DURATION:g}] s, got {args.duration}")
    if not (np.isfinite(args.push_start) and 0 <= args.push_start < args.duration):
        raise SystemExit(f"--push-start must be in [0, --duration) s, got --push-start {args.push_start} with --duration {args.duration}")
    longest = max(args.push_durations)
    if args.push_start + longest > args.duration + 1e-9:
        raise SystemExit(f"--push-start {args.push_start:g} + --push-durations {longest:g} ends after --duration {args.duration:g} s: "
                         "the push must end within the run (its impulse would not be the one reported)")
    if max(args.magnitudes) > MAX_PUSH_FORCE:
        raise SystemExit(f"--magnitudes must be at most {MAX_PUSH_FORCE:g} N, got {max(args.magnitudes):g}")
    if not 1 <= args.directions <= MAX_CASES:
        raise SystemExit(f"--directions must be in [1, {MAX_CASES:,}], got {args.directions}")
    count = len(args.magnitudes) * args.directions * len(args.push_durations)
    if count > MAX_CASES:
        raise SystemExit(f"--magnitudes × --directions × --push-durations: at most {MAX_CASES:,} cases, got {count:,}")
    engine = engine_options(args)
    cases = grid({"magnitude_n": args.magnitudes,
                  "direction_deg": [360.0 * k / args.directions for k in range(args.directions)],
                  "push_duration_s": args.push_durations})
    return cases, engine


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/push_map", duration=3.0, bag=False, meshcat=False)
    parser.add_argument("--magnitudes", type=numbers, default=[150.0, 300.0, 600.0],
                        help=f"forces (N, at most {MAX_PUSH_FORCE:g}), comma-separated")
    parser.add_argument("--directions", type=int, default=4, help="number of directions, evenly spaced from 0°")
    parser.add_argument("--push-durations", type=numbers, default=[0.1, 0.3],
                        help="push durations (s), comma-separated; each push ends within --duration")
    parser.add_argument("--push-start", type=float, default=0.3, help="when the push starts (s)")
    parser.add_argument("--controller", choices=["kinematic", "dynamic"], default="kinematic",
                        help="the SoT on PD actuators (kinematic) or SolverDyn's torques (dynamic)")
    add_sweep_arguments(parser)
    args = parser.parse_args(argv)
    cases, engine = check_options(args)
    start(args)  # (--out checked, and made, before any case)
    settings = {"controller": args.controller, "duration_s": args.duration, "push_start_s": args.push_start, **fall_thresholds()}
    try:
        result = run_sweep(partial(push_case, duration=args.duration, push_start=args.push_start, controller=args.controller),
                           cases, progress=not args.quiet, label="pushes", settings=settings, **engine)
    except EngineUnavailable as error:
        raise SystemExit(str(error)) from error
    paths = result.write(args.out, "push_map")
    figure = plot(result.rows, args.out / "plots.png", args.controller)
    ok = [r for r in result.rows if r["status"] == "ok"]
    summary = {
        "cases": len(cases),
        "errors": len(result.errors),
        "falls": sum(r["fell"] for r in ok),
        "largest_impulse_without_fall_ns": max((r["impulse_ns"] for r in ok if not r["fell"]), default=None),
        "smallest_impulse_with_fall_ns": min((r["impulse_ns"] for r in ok if r["fell"]), default=None),
        "engine": result.engine,
        "workers": result.workers,
        "wall_s": result.wall_s,
        "load_average_before": result.load_average_before,
        "load_average_after": result.load_average_after,
        **settings,
        "tables": {k: str(v) for k, v in paths.items()},
        "plot": None if figure is None else str(figure),
        "case_results": [{k: r.get(k) for k in ("magnitude_n", "direction_deg", "push_duration_s", "impulse_ns", "fell",
                                                "fall_reason", "max_base_tilt_deg", "max_sole_slip_m", "base_drift_m")}
                         for r in ok],
    }
    if args.controller == "dynamic":
        diagram = talos_dynamics.build_diagram("push", "physics", pushes=((args.push_start, 0.1, push_force(100.0, 0.0)),)).diagram
    else:
        diagram = talos_physics.build_diagram("stand", "open", push_force(100.0, 0.0)).diagram
    write_run(args.out, diagram, summary)
    return summary
