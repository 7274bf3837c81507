"""Reachability map of TALOS's right hand: N targets on a grid around the robot, one short
``SolverKine`` run each, the feet, the CoM and the joint limits held.

Each case is the tutorial's stack with the hierarchical QP: ``contactRF``, ``contactLF`` (gain 10,
``keep()``), ``taskCom`` (gain 10, initial CoM), then from t = 0 the hand (``right-wrist`` moved by
``opmodif`` (0.1, 0, 0)) with ``gotoNd(taskRH, target, '111', 8)`` (constant gain 8 /s, damping
1e-2 on the hand's level so that an out-of-reach target stretches the arm smoothly); joint
positions and velocities are hard limits above all tasks (position margin 1e-3 rad). A case lasts
``--duration`` seconds (default 1 s) at ``--dt`` (default 0.02 s: 50 ticks): with gain 8 a
reachable target's error is divided by ~10⁴ in that time. The map asks where the hand can go, not
how precisely the feet hold at this coarse period: it lifts the solver's step limit
(``setStepLimit(inf)``, which at 20 ms would cap the joints at 0.35 rad/s), and the feet then stay
within about 1 mm (``max_foot_drift_m``) instead of 0.1 mm. A case's summary: the final hand error
(m), the smallest joint-limit margin over the run and over the controlled joints (rad; the
grippers, not controlled, start on their limit and are left out) with the joint that has it, and
the largest foot and CoM drifts (m).

Collisions: each case's path is checked with Drake's signed-distance query on a collision world of
its own (every self-collision pair the SRDF and adjacency leave, and every link–obstacle pair), at
every tick: ``min_signed_distance_m`` is the smallest over the run (+inf when no pair came within
5 cm), and a target whose path collides (a distance < 0) is counted as *not* reached, however
close the hand ended. ``--obstacles table`` puts the table top of ``sotdrake.collision.reach``
in front of the robot (``--obstacles path/to/scene.sdf`` any URDF/SDF scene, loaded by
``add_scene``); ``--collision`` adds the collision level (``d_s`` = 1 cm, ``d_i`` = 5 cm, ``ξ`` =
0.5 m/s) between the CoM and the hand, so that the hand stops short instead of going through;
its default period is then 5 ms (``COLLISION_DT``: the level's rows model one tick to first order,
which the unlimited 20 ms steps of the arm break, by up to 7 cm on the grid's far corners), a
period above 10 ms is refused (``MAX_COLLISION_DT``), and the step limit is 0.01 rad or m per tick
(``COLLISION_STEP``; 2 rad/s at 5 ms) instead of none: the level takes in range every pair that
one tick within the solver's step bound may bring within ``d_s``, and a step without bound (the
free base's) would take every pair at every tick.

Targets: ``--targets N`` (at most 100,000) with ``--sampling grid`` (N a cube, k × k × k evenly
spaced in the box x ∈ [-0.4, 0.9], y ∈ [-1.1, 0.5], z ∈ [0.2, 1.8] m, world frame, the robot's
base above the origin facing +x; a single target is the box's centre) or ``--sampling random``
(N uniform in the box, ``--seed``, 0 by default; refused with a grid). A case lasts from one tick
to a day (``--dt`` ≤ ``--duration`` ≤ 86400 s); ``--dt`` must keep ``λ·dt < 2`` for the stack's
largest gain (10 /s: ``--dt`` < 0.2 s). The options are checked, ``--out`` included, before any case
runs.

    python diagrams/reach_map.py --targets 1000 --engine ray --out out/reach_map
    python diagrams/reach_map.py --targets 125 --obstacles table --collision --out out/reach_map_table

writes ``reach_map.csv`` (and ``.parquet`` with pyarrow: one row per target), ``reach_map.json``
(engine, wall time, host load), ``plots.png`` (slices of the workspace: hand error and joint-limit
margin), ``control_graph.svg`` and ``summary.json`` in the output directory.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder

from sotdrake import (
    MAX_DURATION,
    SOT,
    TABLE,
    TALOS_GRIPPERS,
    CollisionWorld,
    InvalidInput,
    MetaTaskKine6d,
    MetaTaskKineCollision,
    Robot,
    SotError,
    Tracer,
    add_obstacle,
    add_scene,
    add_sot,
    gotoNd,
    hold_feet_and_com,
    minimum_distance,
    save_figure,
    script_arguments,
    start,
    talos,
    write_run,
)
from sotdrake.sweep import (
    EngineUnavailable,
    add_sweep_arguments,
    engine_options,
    grid,
    per_process,
    random_cases,
    run_sweep,
)

HAND_OFFSET = (0.1, 0.0, 0.0)
BOX: dict[str, tuple[float, float]] = {"x": (-0.4, 0.9), "y": (-1.1, 0.5), "z": (0.2, 1.8)}
HAND_GAIN = 8.0
#: The gain of the feet and the CoM (1/s, :func:`~sotdrake.hold_feet_and_com`): the stack's largest.
SUPPORT_GAIN = 10.0
#: λ·dt at and above which a gain is refused (``sotdrake.ranges.GAIN_DT_REFUSED``: the loop diverges).
GAIN_DT_REFUSED = 2.0
#: The shortest control period of a case (s), as any ``Robot``'s.
MIN_DT = 1e-6
#: The most targets a map takes (a grid or a random sample).
MAX_TARGETS = 100_000
HAND_DAMPING = 1e-2
REACHED_M = 0.01
#: The default period with the collision level (s): its rows are a first-order model of one tick,
#: which holds for the steps of 5 ms ticks; at 20 ms the arm's unlimited steps cross it.
COLLISION_DT = 0.005
#: The longest period the map takes with the collision level (s): at 20 ms a gripper link crossed
#: the table in one tick.
MAX_COLLISION_DT = 0.01
#: The step limit with the collision level (rad or m per tick): the level takes in range every pair
#: that one tick within the solver's step bound may bring within reach, which an unlimited step
#: (the free base) makes every pair.
COLLISION_STEP = 0.01
#: Pairs farther apart than this (m) are not measured by the collision check.
CHECK_DISTANCE = 0.05


@dataclass
class Reach:
    """Handles on one reach diagram (the hand's target is set per case, in the context)."""

    diagram: Diagram
    robot: Robot
    sot: SOT
    taskRH: MetaTaskKine6d
    tracer: Tracer
    #: a collision world of its own (the same obstacles), for the independent check of each path
    checker: CollisionWorld


def add_obstacles(world, obstacles: str | None) -> None:
    """``obstacles``: None, ``"table"`` (the table top) or the path of a URDF/SDF scene."""
    if obstacles == "table":
        size, centre = TABLE
        add_obstacle(world, ("box", size), np.array([[1, 0, 0, centre[0]], [0, 1, 0, centre[1]], [0, 0, 1, centre[2]], [0, 0, 0, 1]],
                                                    dtype=float), "table")
    elif obstacles is not None:
        add_scene(world, Path(obstacles), None, "scene")


def check_period(dt: float, collision: bool) -> None:
    """:class:`InvalidInput` for a period the map cannot take: below :data:`MIN_DT`, one where the
    stack's largest gain (:data:`SUPPORT_GAIN`) diverges (``λ·dt ≥ 2``), or, with the collision
    level, above :data:`MAX_COLLISION_DT` (the map lifts the step limit)."""
    largest = max(HAND_GAIN, SUPPORT_GAIN)
    if not MIN_DT <= dt < GAIN_DT_REFUSED / largest:
        raise InvalidInput(f"reach map: dt = {dt!r} s: must be in [{MIN_DT:g}, {GAIN_DT_REFUSED / largest:g}) s (λ·dt < "
                           f"{GAIN_DT_REFUSED:g} with the stack's largest gain, λ = {largest:g} 1/s)")
    if collision and not dt <= MAX_COLLISION_DT:
        raise InvalidInput(f"reach map: dt = {dt!r} s with the collision level: at most {MAX_COLLISION_DT:g} s (the map lifts "
                           "the step limit: a longer tick can carry a link through an obstacle in one step)")


def build_diagram(dt: float = 0.02, variant: str = "reduced", obstacles: str | None = None, collision: bool = False) -> Reach:
    """Feet, CoM, the collision level (``collision``) and the right hand under ``SolverKine``, the
    ``obstacles`` (:func:`add_obstacles`); the hand's target is its initial pose until
    :func:`simulate_target` sets one in the context."""
    check_period(dt, collision)
    builder = DiagramBuilder()
    robot = talos(builder, variant, dt)
    sot = add_sot(robot, "sot", solver="hqp", damping=HAND_DAMPING)
    sot.setStepLimit(COLLISION_STEP if collision else np.inf)  # (see the module docstring)
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))
    hold_feet_and_com(robot, sot, SUPPORT_GAIN)
    checker = CollisionWorld(robot.model)
    for world in (robot, checker):
        add_obstacles(world, obstacles)
    if collision:
        sot.push(MetaTaskKineCollision(robot))
    taskRH = MetaTaskKine6d("rh", robot, "rh", robot.OperationalPointsMap["right-wrist"])
    handMgrip = np.eye(4)
    handMgrip[0:3, 3] = HAND_OFFSET
    taskRH.opmodif = handMgrip
    taskRH.feature.frame("desired")
    taskRH.keep()
    taskRH.feature.selec("111")
    sot.push(taskRH.task.name)
    tracer = Tracer(builder, dt)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    diagram = builder.Build()
    diagram.set_name("reach_map")
    return Reach(diagram, robot, sot, taskRH, tracer, checker)


def simulate_target(reach: Reach, target, duration: float) -> Simulator:
    """A fresh simulator on ``reach`` with the hand sent to ``target`` (m, world), run for
    ``duration`` seconds."""
    if not duration > 0:
        raise InvalidInput(f"duration must be > 0 s, got {duration}")
    simulator = Simulator(reach.diagram)
    gotoNd(reach.taskRH, target, "111", HAND_GAIN, context=simulator.get_mutable_context())
    simulator.Initialize()
    simulator.AdvanceTo(duration)
    return simulator


def summarize(reach: Reach, simulator: Simulator, target) -> dict:
    """Hand error, smallest joint-limit margin (controlled joints) and the drifts of one case."""
    robot = reach.robot
    plant = robot.model.plant
    trace = reach.tracer.data(simulator.get_context())
    qs = np.vstack([robot.device.initial_position, trace["q"]])
    path = robot.dynamic.trajectory(["rh", "LF", "RF"], qs)
    hand = path["rh"][:, :3, :3] @ np.asarray(HAND_OFFSET) + path["rh"][:, :3, 3]
    error = np.linalg.norm(hand - np.asarray(target, dtype=float), axis=1)
    joints = [plant.get_joint(j) for j in plant.GetJointIndices()]
    joints = [j for j in joints if j.num_positions() == 1 and j.name() not in TALOS_GRIPPERS]
    index = np.array([j.position_start() for j in joints])
    lower, upper = plant.GetPositionLowerLimits()[index], plant.GetPositionUpperLimits()[index]
    margins = np.minimum(qs[:, index] - lower, upper - qs[:, index]).min(axis=0)
    tightest = int(np.argmin(margins))
    checker_context = reach.checker.new_context()
    distance = min(minimum_distance(reach.checker, checker_context, q, CHECK_DISTANCE) for q in qs)
    return {
        "hand_error_m": float(error[-1]),
        "hand_initial_error_m": float(error[0]),
        "min_signed_distance_m": float(distance),
        "collides": bool(distance < 0.0),
        "reached": bool(error[-1] < REACHED_M and distance >= 0.0),
        "min_joint_limit_margin_rad": float(margins[tightest]),
        "limiting_joint": joints[tightest].name(),
        "max_foot_drift_m": float(max(np.linalg.norm(path[f][:, :3, 3] - path[f][0, :3, 3], axis=1).max() for f in ("LF", "RF"))),
        "max_com_drift_m": float(np.linalg.norm(path["com"] - path["com"][0], axis=1).max()),
        "hand_final_m": hand[-1].tolist(),
    }


def reach_case(case: dict, duration: float = 1.0, dt: float = 0.02, variant: str = "reduced", obstacles: str | None = None,
               collision: bool = False) -> dict:
    """The sweep's case function: ``case = {'x', 'y', 'z'}`` (m) → the case's summary."""
    # One diagram per process (per Ray worker): a pure cache, every case gets a fresh context.
    reach = per_process(("reach_map", dt, variant, obstacles, collision), lambda: build_diagram(dt, variant, obstacles, collision))
    target = (case["x"], case["y"], case["z"])
    simulator = simulate_target(reach, target, duration)
    return summarize(reach, simulator, target)


def targets(count: int, sampling: str = "grid", seed: int = 0, box: dict[str, tuple[float, float]] = BOX) -> list[dict]:
    """``count`` targets (at most :data:`MAX_TARGETS`) in ``box``: a k × k × k grid (``count`` = k³;
    k = 1: the box's centre) or a seeded uniform sample."""
    if isinstance(count, (int, np.integer)) and not isinstance(count, bool) and count > MAX_TARGETS:
        raise InvalidInput(f"--targets must be at most {MAX_TARGETS:,}, got {count}")
    if sampling == "random":
        return random_cases(count, box, seed)
    if sampling != "grid":
        raise InvalidInput(f"sampling is 'grid' or 'random', got {sampling!r}")
    side = round(count ** (1 / 3)) if count > 0 else 0
    if side < 1 or side**3 != count:
        near = sorted({max(side, 1) ** 3, (max(side, 1) + 1) ** 3, max(side - 1, 1) ** 3})
        raise InvalidInput(f"--targets with a grid must be a cube (k³ targets), got {count}; nearest: {near}, "
                           "or use --sampling random")
    return grid({axis: (np.linspace(low, high, side) if side > 1 else np.array([(low + high) / 2])).round(6).tolist()
                 for axis, (low, high) in box.items()})


def plot(rows: list[dict], path: Path, slices: int = 4) -> Path | None:
    """Slices of the workspace at ``slices`` heights: hand error (top) and smallest joint-limit
    margin (bottom) at each target, seen from above; None (nothing written) when no case ran."""
    if not any(r["status"] == "ok" for r in rows):
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    ok = [r for r in rows if r["status"] == "ok"]
    xyz = np.array([[r["x"], r["y"], r["z"]] for r in ok])
    error = np.array([r["hand_error_m"] for r in ok])
    margin = np.array([r["min_joint_limit_margin_rad"] for r in ok])
    heights = np.unique(xyz[:, 2])
    if len(heights) > 12:  # a random sample: slabs of equal thickness
        edges = np.linspace(xyz[:, 2].min(), xyz[:, 2].max() + 1e-9, slices + 1)
        slab = np.clip(np.searchsorted(edges, xyz[:, 2], side="right") - 1, 0, slices - 1)
        labels = [f"z ∈ [{edges[i]:.2f}, {edges[i + 1]:.2f}) m" for i in range(slices)]
        size = 30.0
    else:
        chosen = heights[np.unique(np.linspace(0, len(heights) - 1, min(slices, len(heights))).round().astype(int))]
        slab = np.array([int(np.flatnonzero(chosen == z)[0]) if z in chosen else -1 for z in xyz[:, 2]])
        labels = [f"z = {z:.2f} m" for z in chosen]
        size = 9000 / max(1, len(np.unique(xyz[:, 0])) * len(np.unique(xyz[:, 1])))
    columns = len(labels)
    fig, axes = plt.subplots(2, columns, figsize=(3.6 * columns + 1.2, 7.4), squeeze=False, sharex=True, sharey=True)
    error_norm = LogNorm(vmin=max(1e-5, error.min()), vmax=max(error.max(), 1e-4))
    floor = float(error_norm.vmin) if error_norm.vmin is not None else 1e-5
    for c, label in enumerate(labels):
        here = slab == c
        top = axes[0, c].scatter(xyz[here, 0], xyz[here, 1], c=np.maximum(error[here], floor), s=size,
                                 marker="s", cmap="viridis", norm=error_norm)
        bottom = axes[1, c].scatter(xyz[here, 0], xyz[here, 1], c=margin[here], s=size, marker="s", cmap="magma",
                                    vmin=0.0, vmax=max(0.3, float(np.percentile(margin, 95))))
        reached = here & (error < REACHED_M)
        axes[0, c].scatter(xyz[reached, 0], xyz[reached, 1], s=4, c="w", marker=".")
        axes[0, c].set_title(label, fontsize=10)
        for row in (0, 1):
            axes[row, c].plot(0, 0, "r+", ms=10)  # the base, above the origin
            axes[row, c].set_aspect("equal")
        axes[1, c].set_xlabel("x (m)")
    axes[0, 0].set_ylabel("y (m)")
    axes[1, 0].set_ylabel("y (m)")
    fig.colorbar(top, ax=axes[0, :].tolist(), label="final hand error (m); white dot: < 1 cm")
    fig.colorbar(bottom, ax=axes[1, :].tolist(), label="smallest joint-limit margin (rad)")
    fig.suptitle(f"TALOS right hand, {len(ok)} targets (SolverKine, feet + CoM held); + : base")
    return save_figure(fig, path, tight=False)


def check_options(args: argparse.Namespace) -> tuple[list[dict], dict]:
    """The cases and the engine's options of ``args`` (its ``dt`` set), once every option is
    checked: a ``SystemExit`` naming the first one refused (:func:`~sotdrake.run_script` ends the
    script with it), before anything is written."""
    if args.dt is None:
        args.dt = COLLISION_DT if args.collision else 0.02
    try:
        check_period(args.dt, args.collision)
    except InvalidInput as error:
        raise SystemExit(f"--dt {args.dt}: {error}") from None
    if not args.dt <= args.duration <= MAX_DURATION:
        raise SystemExit(f"--duration must be in [--dt, {MAX_DURATION:g}] s (at least one tick a case), "
                         f"got --duration {args.duration} with --dt {args.dt}")
    if args.seed is not None and args.sampling != "random":
        raise SystemExit(f"--seed {args.seed}: an option of --sampling random (this map is --sampling {args.sampling})")
    if args.seed is not None and args.seed < 0:
        raise SystemExit(f"--seed must be ≥ 0, got {args.seed}")
    engine = engine_options(args)
    try:
        cases = targets(args.targets, args.sampling, args.seed or 0)
        if args.obstacles not in (None, "table"):
            add_scene(CollisionWorld(talos(DiagramBuilder(), "reduced", args.dt).model), Path(args.obstacles), None, "scene")
    except SotError as error:
        raise SystemExit(str(error)) from error
    return cases, engine


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/reach_map", duration=1.0, bag=False, meshcat=False)
    parser.add_argument("--targets", type=int, default=125,
                        help=f"number of targets (a cube with --sampling grid; at most {MAX_TARGETS:,})")
    parser.add_argument("--sampling", choices=["grid", "random"], default="grid",
                        help="grid: k × k × k targets evenly spaced in the box; random: uniform in the box (--seed)")
    parser.add_argument("--seed", type=int, default=None, help="with --sampling random: the random sample's seed (default 0)")
    parser.add_argument("--dt", type=float, default=None, help="control period of each case (s; default 0.02, 0.005 with --collision)")
    parser.add_argument("--obstacles", default=None, help="'table' (the table top) or a URDF/SDF scene file")
    parser.add_argument("--collision", action="store_true", help="add the collision level under the hand")
    add_sweep_arguments(parser)
    args = parser.parse_args(argv)
    cases, engine = check_options(args)
    start(args)  # (--out checked, and made, before any case)
    settings = {"duration_s": args.duration, "dt_s": args.dt, "ticks_per_case": round(args.duration / args.dt),
                "hand_gain": HAND_GAIN, "hand_damping": HAND_DAMPING, "sampling": args.sampling,
                "seed": (args.seed or 0) if args.sampling == "random" else None, "box_m": BOX, "obstacles": args.obstacles,
                "collision_level": args.collision}
    try:
        case = partial(reach_case, duration=args.duration, dt=args.dt, obstacles=args.obstacles, collision=args.collision)
        result = run_sweep(case, cases, progress=not args.quiet, label="reach targets", settings=settings, **engine)
    except EngineUnavailable as error:
        raise SystemExit(str(error)) from error
    paths = result.write(args.out, "reach_map")
    figure = plot(result.rows, args.out / "plots.png")
    ok = [r for r in result.rows if r["status"] == "ok"]
    summary = {
        "targets": len(cases),
        "errors": len(result.errors),
        "reached_within_1cm": sum(r["reached"] for r in ok),
        "colliding_paths": sum(r["collides"] for r in ok),
        "min_signed_distance_m": min((r["min_signed_distance_m"] for r in ok), default=None),
        "min_joint_limit_margin_rad": min((r["min_joint_limit_margin_rad"] for r in ok), default=None),
        "max_foot_drift_m": max((r["max_foot_drift_m"] for r in ok), default=None),
        "max_com_drift_m": max((r["max_com_drift_m"] for r in ok), default=None),
        "engine": result.engine,
        "workers": result.workers,
        "wall_s": result.wall_s,
        "cases_per_s": len(cases) / result.wall_s,
        "load_average_before": result.load_average_before,
        "load_average_after": result.load_average_after,
        **settings,
        "tables": {k: str(v) for k, v in paths.items()},
        "plot": None if figure is None else str(figure),
    }
    write_run(args.out, build_diagram(args.dt, obstacles=args.obstacles, collision=args.collision).diagram, summary)
    return summary
