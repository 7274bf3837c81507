"""The walk scenario (``diagrams/walk.py``): the walking controller of
:mod:`sotdrake.walking.controller` run from the command line, its summary (tracking, ZMP margins,
slip, realised velocity, falls) and its plots.

The seed's kinematic walk (walkromeo) on TALOS or Romeo: a pattern generator commanded by velocity
(``--velocity``, ``--then T X Y THETA``) or by a list of steps (``--steps N --step-length L``), in
one of three modes (``--mode kinematic | physics | dynamic``).

``pg.setVelocity(x, y, θ)`` (the ``PatternGenerator``: footsteps, ZMP reference, CoM by Drake's
``ZmpPlanner``, swing trajectories) feeds the desired values of the seed's stack, in priority
order: the waist's height, roll and pitch (``taskWaist``, ``'011100'``), both soles in 6D
(``taskRF``, ``taskLF``), the CoM in x, y (``taskCom``, ``'011'``, with the planned CoM velocity as
feed-forward), then the head's orientation following the right foot (``taskHead``, ``'110000'``: pitch and yaw),
the waist's yaw (``taskWaistOr``, ``'100000'``) and walkromeo's arm task, the arm joints held at
half-sitting by a posture task at the bottom (``taskArms``, gain 0.1 /s; ``--arms posture``, the
default); ``--arms inequality``: instead, with ``SolverKine`` (``--solver hqp``, the default), both
wrists kept from moving backward relative to the waist (``taskArmL``, ``taskArmR``:
``TaskInequality`` on the x of ``FeatureRelative6d``). Every moving target comes with its velocity
(feed-forward).

``--mode kinematic``: the SoT integrates its velocity at 1 kHz (no dynamics). ``--mode physics``:
the same control graph drives the physically simulated TALOS through position servos (the PD
actuators of :mod:`sotdrake.physics`, open loop, as ``diagrams/talos_physics.py``), with the
servo options of :class:`~sotdrake.walking.controller.Servos` (``--stiffness``, ``--damping``, the static feed-forward torque with
``--feedforward``, the CoM/ZMP stabiliser's ``--com-gain``/``--zmp-gain``, on by default) and the gait's
``--landing-depth``; its CoM is planned with the legs' momentum (the multibody ZMP correction of
:mod:`sotdrake.walking.multibody_zmp`; ``--zmp-model lipm``: the pendulum alone, ``--zmp-model
multibody`` in kinematic mode). ``--mode dynamic``: ``SolverDyn`` drives the torque-controlled TALOS, the soles'
contacts released and added back at each step (``rmContact``/``addContact``; ``--steps`` only), the
swing quintic (``--swing-profile``; zero acceleration at the lift-off: with the cubic, the stance
sole spins when the other foot lifts off).
``--then T X Y THETA`` changes the command at time T (``attime``); ``--steps N --step-length L``
walks N steps of L metres (the walking frame's advance per step) instead of a velocity.
``--robot romeo`` walks Romeo (kinematic mode: the physics station is TALOS').

    python diagrams/walk.py --robot talos --velocity 0.1 0 0 --then 10 0.1 0 0.1 --duration 15 --out out/walk
    python diagrams/walk.py --mode physics --steps 8 --step-length 0.2 --duration 10 --out out/walk_physics
    python diagrams/walk.py --mode dynamic --steps 8 --step-length 0.2 --duration 10 --out out/walk_dynamic
    python diagrams/walk.py --robot romeo --velocity 0.1 0 0 --duration 6 --out out/walk_romeo
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from sotdrake import (
    InvalidInput,
    fall_report,
    options_given,
    save_figure,
    script_arguments,
    simulate,
    start,
    tilt_of_rotations,
    write_run,
)
from sotdrake.walking import GaitParameters, motion_zmp
from sotdrake.walking.com_planner import GRAVITY
from sotdrake.walking.controller import (
    ARMS,
    DYNAMIC_SWING_PROFILE,
    MAX_STEPS,
    MODES,
    POSTURE_GAIN,
    ROBOTS,
    SEED_GAINS,
    TRACKING_GAIN,
    Servos,
    Walk,
    build_diagram,
)
from sotdrake.walking.support import footprint, polygon_margin, support_polygon

#: A sole carrying more than this (N) stands: its motion then is slip.
SLIP_LOAD_N = 100.0
#: The walk's control period (s): ``--duration`` is at least one tick.
DT = 1e-3


# --- post-processing ------------------------------------------------------------------------
def _planar(poses: np.ndarray) -> np.ndarray:
    """(k, 4, 4) poses → (k, 3) ``(x, y, yaw)``."""
    return np.column_stack([poses[:, 0, 3], poses[:, 1, 3], np.unwrap(np.arctan2(poses[:, 1, 0], poses[:, 0, 0]))])


def _segment_velocity(t, base, plan, t0, t1, gait: GaitParameters) -> tuple[np.ndarray, float, float] | None:
    """Mean realised velocity ``(vx, vy, ω)`` (walking frame at the window's start) of the base
    over a whole, even number of steps inside ``[t0, t1]``: between touch-downs, from the second
    step after ``t0 + start_duration`` (a new command applies from the next step)."""
    touchdowns = [s.touchdown for s in plan.steps if t0 + gait.start_duration + 2 * gait.step_duration <= s.touchdown <= t1]
    if len(touchdowns) < 3:
        return None
    a, b = touchdowns[0], touchdowns[-1 - (len(touchdowns) - 1) % 2]
    ia, ib = np.searchsorted(t, a), np.searchsorted(t, b)
    return _mean_velocity(base[ia], base[ib], b - a), a, b


def _mean_velocity(start, end, duration: float) -> np.ndarray:
    """``(vx, vy, ω)`` from base poses ``(x, y, yaw)`` at the same phase of the gait ``duration``
    apart: the displacement in the walking frame at mid-turn, the chord of a circular arc turned
    into its length (``arc = chord · (Δθ/2) / sin(Δθ/2)``)."""
    turn = end[2] - start[2]
    heading = start[2] + turn / 2
    c, s = np.cos(heading), np.sin(heading)
    dx, dy = end[:2] - start[:2]
    chord_to_arc = 1.0 if abs(turn) < 1e-9 else (turn / 2) / np.sin(turn / 2)
    return np.array([c * dx + s * dy, -s * dx + c * dy, turn]) * np.array([chord_to_arc, chord_to_arc, 1.0]) / duration


def _stretches(flags: np.ndarray) -> list[np.ndarray]:
    """The index ranges where ``flags`` is True, each as an array of indices."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flags.astype(int), [0]])))
    return [np.arange(a, b) for a, b in zip(edges[::2], edges[1::2], strict=False)]


def _slips(path: dict, feet: tuple[str, str], trace: dict, plan, physics: bool) -> list[float]:
    """How far (m, xy) each sole moves while it stands, one figure a stance: kinematic, over each
    planned stance (touch-down to the next lift-off); physics, over each stretch where it carries
    more than :data:`SLIP_LOAD_N` (a sole that lands early, late or bounces moves in the air: a
    tracking error, not slip)."""
    t = trace["time"]
    slips = []
    for i, side in enumerate(("left", "right")):
        xy = path[feet[i]][:, :2, 3]
        if physics:
            stretches = _stretches(trace["contact"][:, 2 + 3 * i] > SLIP_LOAD_N)
        else:
            landings = [0.0] + [st.touchdown for st in plan.steps if st.side == side]
            liftoffs = [st.liftoff for st in plan.steps if st.side == side] + [np.inf]
            stretches = [np.flatnonzero((t >= down) & (t <= up)) for down, up in zip(landings, liftoffs, strict=False)]
        slips += [float(np.linalg.norm(xy[k] - xy[k[0]], axis=1).max()) for k in stretches if k.size > 1]
    return slips


def _velocity_segments(trace: dict, base: np.ndarray, plan, gait: GaitParameters, duration: float,
                       then=None) -> list[dict | None]:
    """Each command's realised velocity (:func:`_segment_velocity`) against the command: the
    command from t = 0, then ``then``'s from its time; None for a segment too short to measure or
    without a velocity command (a list of steps)."""
    t = trace["time"]
    change = then[0] if then is not None else duration
    segments = [(0.0, change, trace["pg_velocity_command"][0])]
    if then is not None:
        segments.append((change, duration, np.asarray(then[1:], dtype=float)))
    ratios: list[dict | None] = []
    for t0, t1, command in segments:
        measured = _segment_velocity(t, base, plan, t0, t1, gait)
        if measured is None or not np.any(command):
            ratios.append(None)
            continue
        v, a, b = measured
        linear = np.linalg.norm(command[:2])
        ratio = float(np.linalg.norm(v[:2] - command[:2]) / linear) if linear else None
        ratios.append({"command": command.tolist(), "realised": v.tolist(), "window_s": [a, b], "linear_ratio": ratio,
                       "yaw_rate_ratio": abs(v[2] - command[2]) / abs(command[2]) if command[2] else None})
    return ratios


def summarize(walk: Walk, simulator, duration: float, wall: float, then=None) -> tuple[dict, dict]:
    """The walk's figures after ``duration`` s (``wall`` s of wall clock) and its trace: the feet's and
    the CoM's tracking errors (m; ``q[k]`` against the references of tick ``k + 1``), the planned
    ZMP's margin in the support polygon, slip, the base's final distance from the plan, the realised
    velocity of each command (``then``: the second one), falls; physics modes add the CoP's margin."""
    context = simulator.get_context()
    trace = walk.tracer.data(context)
    if len(trace["time"]) < 2:  # (the errors compare each tick's q with the next tick's references)
        raise InvalidInput(f"summarize: the run must last at least one tick ({walk.robot.dt:g} s), got {context.get_time():g} s")
    bot, spec, gait = walk.robot, walk.spec, walk.pg.gait
    nq = bot.model.nq
    physics = walk.mode in ("physics", "dynamic")
    qs = trace["x_plant"][:, :nq] if physics else trace["q_device"]
    t = trace["time"]
    path = bot.dynamic.trajectory([spec.feet[0], spec.feet[1], spec.waist], qs)
    plan = walk.pg.plan(context)
    feet_ref = trace["pg_feet"]
    # Each tick's q (logged after its update) is what the next tick's tasks see: compare q[k]
    # with the references at k + 1.
    foot_errors = np.concatenate([np.linalg.norm(path[spec.feet[i]][:-1, :3, 3] - feet_ref[1:, 4 * i : 4 * i + 3], axis=1)
                                  for i in range(2)])
    com_error = np.linalg.norm(path["com"][:-1, :2] - trace["pg_com"][1:, :2], axis=1)
    # Planned ZMP (of the planned CoM) and reference against the planned support polygons.
    zmp_planned = trace["pg_com"][:, :2] - trace["pg_com"][:, 2:3] / GRAVITY * trace["pg_com_acceleration"][:, :2]
    polygons = [plan.support_polygon(tk, gait) for tk in t]
    zmp_margin = np.array([polygon_margin(z, P) for z, P in zip(zmp_planned, polygons, strict=False)])
    ref_margin = np.array([polygon_margin(z, P) for z, P in zip(trace["pg_zmp_reference"], polygons, strict=False)])
    base = _planar(path[spec.waist])
    base_z = path[spec.waist][:, 2, 3]
    fall = fall_report(t, tilt_of_rotations(path[spec.waist]), base_z)  # (the soles move: no slip criterion)
    # The planned base: the planned CoM plus the start's base-to-CoM offset (turned with the feet).
    q0 = bot.q0 if walk.mode == "dynamic" else bot.device.initial_position
    offset0 = bot.dynamic.pose_at(spec.waist, q0).translation()[:2] - bot.dynamic.com_at(q0)[:2]
    yaw_ref = 0.5 * (feet_ref[-1, 3] + feet_ref[-1, 7]) - 0.5 * (feet_ref[0, 3] + feet_ref[0, 7])
    c, s = np.cos(yaw_ref), np.sin(yaw_ref)
    planned_base = trace["pg_com"][-1, :2] + np.array([c * offset0[0] - s * offset0[1], s * offset0[0] + c * offset0[1]])
    final_error = float(np.linalg.norm(base[-1, :2] - planned_base))
    slips = _slips(path, spec.feet, trace, plan, physics)
    summary = {
        "robot": walk.robot_name,
        "mode": walk.mode,
        "solver": type(walk.sot).__name__,
        **fall,
        "max_foot_tracking_error_m": float(foot_errors.max()),
        "max_com_tracking_error_m": float(com_error.max()),
        "min_zmp_margin_m": float(zmp_margin.min()),
        "min_zmp_reference_margin_m": float(ref_margin.min()),
        "max_zmp_planned_minus_reference_m": float(np.linalg.norm(zmp_planned - trace["pg_zmp_reference"], axis=1)[1:].max()),
        "final_position_error_m": final_error,
        "max_slip_per_step_m": max(slips) if slips else 0.0,
        "steps": int(sum(1 for st in plan.steps if st.touchdown <= t[-1])),
        "input_cost": walk.pg.input_cost,
    }
    # The multibody ZMP of the motion the SoT commands (the device's q, Drake's momentum), every
    # 10 ticks from the first lift-off: how far the whole body's ZMP strays from the reference.
    liftoffs = [st.liftoff for st in plan.steps]
    walking = np.flatnonzero(t >= liftoffs[0])[::10] if liftoffs else np.array([], dtype=int)
    if walking.size >= 5 and "q_device" in trace:  # (the dynamic walk traces no device)
        device_zmp, _ = motion_zmp(bot.model.plant, t[walking], trace["q_device"][walking][:, :nq])
        error = np.linalg.norm(device_zmp - trace["pg_zmp_reference"][walking], axis=1)[2:-2]  # (one-sided differences at the ends)
        summary["max_multibody_zmp_minus_reference_m"] = float(error.max())
        summary["multibody_zmp_correction"] = walk.pg.legs is not None
    ratios = _velocity_segments(trace, base, plan, gait, duration, then)
    summary["velocity_error_ratio"] = ratios[0]["linear_ratio"] if ratios[0] else None
    summary["velocity_segments"] = ratios
    if physics:
        contact = trace["contact"]
        loaded = np.column_stack([contact[:, 2] > 20.0, contact[:, 5] > 20.0])
        soles = [_planar(path[spec.feet[i]]) for i in range(2)]
        cop_margin = [polygon_margin(contact[k, 6:8], support_polygon([soles[i][k] for i in range(2) if loaded[k, i]], gait))
                      for k in range(1, len(t)) if loaded[k].any() and np.all(np.isfinite(contact[k, 6:8]))]
        summary["min_cop_margin_m"] = float(min(cop_margin)) if cop_margin else None
        summary["servos"] = dataclasses.asdict(walk.servos) if walk.servos is not None else None
        trace["cop"] = contact[:, 6:8]
    else:
        summary["min_cop_margin_m"] = None  # no contact forces without physics
    summary.update(duration_s=duration, dt_s=bot.dt, wall_s=wall, realtime_factor=duration / wall)
    trace.update(base=base, com_realised=path["com"], zmp_planned=zmp_planned, zmp_margin=zmp_margin,
                 foot_error=np.column_stack(np.split(foot_errors, 2)), com_error=com_error)
    return summary, trace


def plot(walk: Walk, simulator, trace: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    gait, plan = walk.pg.gait, walk.pg.plan(simulator.get_context())
    t = trace["time"]
    fig, axes = plt.subplots(2, 2, figsize=(14, 9))
    ax = axes[0, 0]
    poses = [plan.start.foot("left"), plan.start.foot("right")] + [(s.x, s.y, s.yaw) for s in plan.steps if s.touchdown <= t[-1]]
    for k, pose in enumerate(poses):
        ax.add_patch(Polygon(footprint(pose, gait), closed=True, fill=False, color="C0" if k % 2 == 0 else "C3", lw=0.8))
    ax.plot(trace["pg_zmp_reference"][:, 0], trace["pg_zmp_reference"][:, 1], "k--", lw=0.8, label="ZMP reference")
    ax.plot(trace["zmp_planned"][:, 0], trace["zmp_planned"][:, 1], "g", lw=0.8, label="ZMP of the planned CoM")
    ax.plot(trace["pg_com"][:, 0], trace["pg_com"][:, 1], "b", lw=1.2, label="CoM planned")
    ax.plot(trace["com_realised"][:, 0], trace["com_realised"][:, 1], "m:", lw=1.2, label="CoM realised")
    if "cop" in trace:
        ax.plot(trace["cop"][:, 0], trace["cop"][:, 1], ".", color="orange", ms=0.6, label="CoP (physics)")
    ax.set_aspect("equal")
    ax.set_title("footprints, CoM and ZMP")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    ax.plot(t, trace["zmp_margin"], label="planned ZMP margin in the support polygon")
    ax.axhline(0.02, color="grey", ls=":", lw=0.8)
    ax.set_ylabel("margin (m)")
    ax.set_xlabel("time (s)")
    ax.set_title("planned ZMP margin (dotted: the 2 cm target)")
    ax.legend(fontsize=7)
    ax = axes[1, 0]
    window = max(1, round(2 * gait.step_duration / walk.robot.dt))  # a left and a right step: the sway cancels
    base = trace["base"]
    if len(base) > window:
        rate = (base[window:] - base[:-window]) / (window * walk.robot.dt)
        yaw = base[:-window, 2]
        forward = np.cos(yaw) * rate[:, 0] + np.sin(yaw) * rate[:, 1]
        lateral = -np.sin(yaw) * rate[:, 0] + np.cos(yaw) * rate[:, 1]
        tm = t[:-window] + 0.5 * window * walk.robot.dt
        ax.plot(tm, forward, "C0", label="realised vx (mean over two steps)")
        ax.plot(tm, lateral, "C1", label="realised vy")
        ax.plot(tm, rate[:, 2], "C2", label="realised ω")
        planned = (trace["pg_com"][window:, :2] - trace["pg_com"][:-window, :2]) / (window * walk.robot.dt)
        ax.plot(tm, np.cos(yaw) * planned[:, 0] + np.sin(yaw) * planned[:, 1], "k:", lw=1.0,
                label="planned vx (the CoM plan, mean over two steps)")
    command = trace["pg_velocity_command"]
    if np.any(command):  # a velocity command (a list of footsteps has none)
        for i, name in enumerate(("vx", "vy", "ω")):
            ax.plot(t, command[:, i], f"C{i}--", lw=0.8, label=f"commanded {name}")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("m/s, rad/s")
    ax.set_title("commanded, planned and realised velocity (base frame)")
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    ax.semilogy(t[1:], np.maximum(trace["foot_error"], 1e-9), label=["left sole", "right sole"])
    ax.semilogy(t[1:], np.maximum(trace["com_error"], 1e-9), label="CoM xy")
    ax.axhline(1e-3, color="grey", ls=":", lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("tracking error (m)")
    ax.set_title("feet and CoM tracking (dotted: 1 mm)")
    ax.legend(fontsize=7)
    fig.suptitle(f"walk: {walk.robot_name}, {walk.mode} mode, {len(poses) - 2} steps shown")
    return save_figure(fig, path)


def _gait(parser: argparse.ArgumentParser, args: argparse.Namespace) -> GaitParameters:
    """The robot's gait with the timing options of ``args`` (a refused value, 0 included: the option
    named); an option not given keeps the robot's value."""
    gait = ROBOTS[args.robot].gait
    for option, value in (("--step-duration", args.step_duration), ("--single-support", args.single_support)):
        if value is not None and not value > 0:
            parser.error(f"{option} {value}: must be > 0 s")
    try:
        if args.step_duration is not None or args.single_support is not None:
            duration = args.step_duration if args.step_duration is not None else gait.step_duration
            single = args.single_support if args.single_support is not None else duration - gait.double_support
            gait = dataclasses.replace(gait, step_duration=duration, single_support=single)
        if args.landing_depth is not None:
            gait = dataclasses.replace(gait, landing_depth=args.landing_depth)
    except InvalidInput as error:
        parser.error(f"--step-duration {args.step_duration}, --single-support {args.single_support}, "
                     f"--landing-depth {args.landing_depth}: {error}")
    if args.swing_profile is not None or args.mode == "dynamic":
        gait = dataclasses.replace(gait, swing_profile=args.swing_profile or DYNAMIC_SWING_PROFILE)
    return gait


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/walk", duration=15.0)
    parser.add_argument("--robot", choices=sorted(ROBOTS), default="talos")
    parser.add_argument("--velocity", type=float, nargs=3, default=(0.1, 0.0, 0.0), metavar=("X", "Y", "THETA"))
    parser.add_argument("--then", type=float, nargs=4, default=None, metavar=("T", "X", "Y", "THETA"),
                        help="pg.setVelocity(X, Y, THETA) at time T")
    parser.add_argument("--steps", type=int, default=None, help="walk this many steps instead of a velocity")
    parser.add_argument("--step-length", type=float, default=None, help="with --steps: advance per step (m; default 0.2)")
    parser.add_argument("--mode", choices=MODES, default="kinematic")
    parser.add_argument("--solver", choices=["hqp", "cascade"], default="hqp")
    parser.add_argument("--gains", type=float, nargs=2, default=(TRACKING_GAIN, POSTURE_GAIN), metavar=("TRACKING", "ORIENTATION"),
                        help=f"the tracking and orientation gains (1/s; walkromeo's: {SEED_GAINS[0]:g} {SEED_GAINS[1]:g})")
    parser.add_argument("--arms", choices=ARMS, default="posture",
                        help="posture: walkromeo's, the arm joints held at half-sitting; inequality: the wrists kept from "
                             "moving backward (hqp only)")
    parser.add_argument("--step-duration", type=float, default=None, help="a step's duration (s; default 0.8, as walkromeo)")
    parser.add_argument("--single-support", type=float, default=None, help="its single support (s; default 0.7)")
    parser.add_argument("--landing-depth", type=float, default=None, help="the swing ends this far below the ground (m; default 0)")
    parser.add_argument("--swing-profile", choices=["cubic", "quintic"], default=None,
                        help="the swing's profile (default: quintic in dynamic mode, else cubic)")
    defaults = Servos()
    parser.add_argument("--stiffness", type=float, default=defaults.stiffness, help="physics: servo kp = STIFFNESS · effort limit (1/rad)")
    parser.add_argument("--damping", type=float, default=defaults.damping, help="physics: servo kd = DAMPING · kp (s)")
    parser.add_argument("--feedforward", action="store_true", help="physics: the static feed-forward torque in the servos")
    parser.add_argument("--com-gain", type=float, default=defaults.com_gain, help="physics: the stabiliser's CoM gain k_c (1/s; 0: none)")
    parser.add_argument("--zmp-gain", type=float, default=defaults.zmp_gain, help="physics: the stabiliser's ZMP gain k_z (1/s)")
    parser.add_argument("--closed-loop", action="store_true", help="physics: the SoT reads the plant's q (perfect estimation)")
    parser.add_argument("--zmp-model", choices=["lipm", "multibody"], default=None,
                        help="the CoM plan: the pendulum alone, or with the legs' momentum (default: multibody in physics mode)")
    args = parser.parse_args(argv)
    physics_only = options_given(parser, args, ("stiffness", "damping", "feedforward", "com_gain", "zmp_gain", "closed_loop"))
    if physics_only and args.mode != "physics":
        parser.error(f"{', '.join(physics_only)}: options of --mode physics (this run is --mode {args.mode})")
    if args.steps is not None and not 1 <= args.steps <= MAX_STEPS:
        parser.error(f"--steps must be in [1, {MAX_STEPS}], got {args.steps}")
    if args.steps is None and args.step_length is not None:
        parser.error("--step-length: an option of --steps (this run walks at --velocity)")
    if args.steps is not None and options_given(parser, args, ("velocity",)):
        parser.error("--velocity: this run walks --steps (give one or the other)")
    gait = _gait(parser, args)
    if args.duration < DT:
        raise SystemExit(f"--duration must be at least one tick ({DT:g} s), got {args.duration}")
    meshcat = start(args)
    steps = (args.steps, 0.2 if args.step_length is None else args.step_length) if args.steps is not None else None
    servos = Servos(args.stiffness, args.feedforward, args.com_gain, args.zmp_gain, args.closed_loop, args.damping)
    velocity = None if steps is not None else args.velocity
    walk = build_diagram(args.robot, velocity, args.then, steps, args.mode, args.solver, DT, gait=gait, meshcat=meshcat,
                         servos=servos, multibody_zmp=None if args.zmp_model is None else args.zmp_model == "multibody",
                         arms=args.arms, gains=tuple(args.gains))
    simulator, wall = simulate(walk.diagram, args.duration, walk.visualizer, not args.quiet)
    summary, trace = summarize(walk, simulator, args.duration, wall, args.then)
    args.out.mkdir(parents=True, exist_ok=True)
    plot(walk, simulator, trace, args.out / "plots.png")
    write_run(args.out, walk.diagram, summary, trace, meshcat, walk.visualizer, bag=args.bag)
    return summary
