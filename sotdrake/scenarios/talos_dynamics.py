"""The dynamic SoT: TALOS under torque control (SolverDyn), standing, swaying, lifting a leg.

The seed's dynamic level: ``SolverDyn`` computes ``(q̈, f, τ)`` in strict priority (dynamics,
contacts with friction/CoP/torque/joint limits, then the stack, then damping). ``--device physics``
sends ``τ`` to the actuation input of a simulated TALOS (no PD, 1 kHz, closed loop on the plant's
state); ``--device dynsimu`` integrates ``q̈`` (``RobotDynSimu``, no physics). Scenarios:

* ``stand``: both soles held, CoM and posture held;
* ``sway``: the CoM follows ``y = y0 + e(t) · 5 cm · sin(2π · 0.5 t)`` (velocity and acceleration
  feed-forward), the amplitude faded in by a minimum-jerk envelope ``e`` over the first 2 s (a
  sine started at full amplitude asks a step of 16 cm/s at t = 0);
* ``lift_leg`` (the seed's dynromeo): the CoM moves over the left sole (t = 0.5 → 2 s), the right
  contact is released at 2.2 s (its force ramps to 0 over 0.3 s), then the right sole rises 10 cm
  (2.5 → 3.5 s) and stays up;
* ``lift_leg_no_com``: the same without the CoM task (the seed's "what happens?");
* ``squat``: the CoM goes 15 cm down (0.5 → 1.5 s) and back up (2 → 3 s);
* ``push``: standing, 500 N × 2 ms at t = 1 s and 100 N × 0.1 s at t = 2 s on the torso (+x);
  the CoM task is softer (``PUSH_COM_KP``): after the long push (10 N·s, the CoM at 0.11 m/s) a
  stiff one asks a deceleration no CoP inside the soles can give; ``--momentum-damping KV`` adds an
  angular-momentum damping task under the CoM task (``diagrams/push_momentum.py`` compares pushes).

    python diagrams/talos_dynamics.py --scenario lift_leg --device physics --duration 5 --out out/dyn_lift
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams
from pydrake.multibody.meshcat import ContactVisualizer, ContactVisualizerParams
from pydrake.multibody.plant import ExternallyAppliedSpatialForceMultiplexer
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Multiplexer
from pydrake.systems.rendering import MultibodyPositionToGeometryPose
from pydrake.trajectories import PiecewisePolynomial

from sotdrake import (
    CONTACT_MODELS,
    CONTACT_SOLVERS,
    TALOS_GRIPPERS,
    InvalidInput,
    Tracer,
    add_task_weight,
    attime,
    load_talos,
    options_given,
    script_arguments,
    start,
    write_run,
)
from sotdrake.dynamics.contact import friction_ratio
from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynMomentum, MetaTaskDynPosture
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.dynamics.station import sole_rectangle
from sotdrake.dynamics.trajectories import hold_move_hold, minimum_jerk_moves, trajectory_ports
from sotdrake.hqp import ACTIVE_SET, SOLVERS
from sotdrake.physics import FRICTION, ContactMonitor, Push
from sotdrake.scenarios.common import floating_base_fall, point_drift, translation_drift
from sotdrake.scenarios.figures import dynamics_figure, support_box

SCENARIOS = ("stand", "sway", "lift_leg", "lift_leg_no_com", "squat", "push")
SWAY = (0.05, 0.5, 2.0)  # amplitude (m), frequency (Hz), fade-in (s)
COM_SHIFT = (0.5, 2.0)  # lift_leg: the CoM moves over the left sole in this window (s)
RELEASE = (2.2, 0.3)  # lift_leg: rmContact time (s), ramp duration (s)
LIFT = (2.5, 3.5, 0.10)  # lift_leg: the right sole rises 10 cm in this window (s)
SQUAT = (0.5, 1.5, 2.0, 3.0, 0.15)  # down from, to, up from, to (s), depth (m)
PUSHES = ((1.0, 0.002, 500.0), (2.0, 0.1, 100.0))  # start (s), duration (s), force along +x (N)
#: Each held sole presses at least this hard (N). On the compliant soles a sole held at 1 N creeps:
#: in the sway (3 s) it moved 48 µm, at 30 N 4.9 µm.
F_MIN = 30.0
#: The CoM task's K_p (1/s², K_v = 2√K_p). The CoM can only accelerate as far as the CoP stays in
#: the soles, ``|c̈_x| ≤ g d/z ≈ 1 m/s²`` (d ≈ 9 cm from the ankles to the toes' margin, z = 0.87 m).
#: After the long push the CoM moves at 0.11 m/s: K_v = 20 (K_p = 100) asks 2.2 m/s², the CoM
#: level is then infeasible and the hierarchy spends all the freedom below the contacts on it
#: (torques at their limits, 2 cm of slip); K_v = 8.9 (K_p = 20) asks 1 m/s².
COM_KP = 100.0
PUSH_COM_KP = 20.0
#: The contacts' ``K_v`` (1/s; ``K_v dt ≤ 0.1``) and ``K_p = K_v²/4`` on ``dynsimu``, which integrates ``q̈`` exactly: with
#: ``K_p = 0`` the held soles drift (0.18 mm in the squat), with these 0.0086 mm, the other figures unchanged. On the
#: physics plant the ground holds the soles (its compliance, not an integration error): the defaults there.
DYNSIMU_CONTACT_KV = 100.0
#: The soles land on the plant's contact in the first instants: ``max_friction_ratio_settled`` is
#: taken from then on (``max_friction_ratio``: the whole run).
SETTLING_S = 0.05


@dataclass
class DynamicsRun:
    diagram: Diagram
    robot: RobotDyn
    tracer: Tracer
    scenario: str
    device: str
    com: MetaTaskDynCom | None
    foot: MetaTaskDyn6d | None
    monitor: ContactMonitor | None
    com_reference: np.ndarray  # the CoM reference's constant part (the initial CoM)
    visualizer: Any = None
    contact: tuple[str, str] | None = None  # the physics device's soles and contact solver


def sway_reference(t: float) -> tuple[float, float, float]:
    """``(y, ẏ, ÿ) − y0`` of the sway at time t (see the module docstring)."""
    amplitude, frequency, fade = SWAY
    w = 2 * np.pi * frequency
    tau = min(t / fade, 1.0)
    e = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    de = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / fade if tau < 1 else 0.0
    dde = (60 * tau - 180 * tau**2 + 120 * tau**3) / fade**2 if tau < 1 else 0.0
    sin, cos = np.sin(w * t), np.cos(w * t)
    return (amplitude * e * sin, amplitude * (de * sin + e * w * cos),
            amplitude * (dde * sin + 2 * de * w * cos - e * w**2 * sin))


def _com_trajectory(scenario: str, com0: np.ndarray, left_sole_xy: np.ndarray, duration: float = 30.0) -> PiecewisePolynomial | None:
    if scenario == "sway":  # Drake's cubic Hermite spline through the exact values and rates, every 5 ms
        times = np.arange(0.0, duration + 1e-9, 0.005)
        values = np.array([com0 + [0.0, sway_reference(t)[0], 0.0] for t in times]).T
        rates = np.array([[0.0, sway_reference(t)[1], 0.0] for t in times]).T
        return PiecewisePolynomial.CubicHermite(times, values, rates)
    if scenario == "lift_leg":
        target = com0.copy()
        target[:2] = left_sole_xy
        return hold_move_hold(*COM_SHIFT, com0, target)
    if scenario == "squat":
        down = com0 - np.array([0.0, 0.0, SQUAT[4]])
        t0, t1, t2, t3, _ = SQUAT
        return minimum_jerk_moves(com0, [(t0, t1, down), (t2, t3, com0)])
    return None


def build_diagram(scenario: str = "stand", device: str = "physics", meshcat: Meshcat | None = None, dt: float = 1e-3,
                  solver: str = ACTIVE_SET, effort_scale: float = 1.0, momentum_damping: float | None = None,
                  pushes: tuple | None = None, momentum_weight: float | None = None, contact: str = "hydroelastic",
                  contact_solver: str = "sap") -> DynamicsRun:
    """``contact`` and ``contact_solver``: the physics device's soles and contact solver (:class:`RobotDyn`);
    ``effort_scale``: the solver's torque bounds as a fraction of TALOS' effort limits;
    ``momentum_damping``: ``K_v`` (1/s) of an angular-momentum damping task under the CoM task
    (``MetaTaskDynMomentum``), None for none, or, with ``momentum_weight``, in one weighted level with
    the posture (``add_task_weight``: posture 1, momentum ``momentum_weight``); ``pushes``: ``(start
    s, duration s, force N (world 3-vector))`` on the torso, with the physics device (default: the
    ``push`` scenario's :data:`PUSHES`, none otherwise)."""
    if scenario not in SCENARIOS:
        raise ValueError(f"unknown scenario {scenario!r}; available: {SCENARIOS}")
    builder = DiagramBuilder()
    model = load_talos("reduced")
    robot = RobotDyn(builder, model, device, dt, solver=solver, effort_scale=effort_scale, contact=contact,
                     contact_solver=contact_solver)
    sot, connect = robot.sot, builder.Connect
    # As in the tutorial, the grippers (on their upper limit at the start) are left out: q̈ = 0.
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))
    contactLF = robot.add_contact("contactLF", "left-sole", f_min=F_MIN)
    contactRF = robot.add_contact("contactRF", "right-sole", f_min=F_MIN)
    sot.addContact(contactLF)
    sot.addContact(contactRF)
    if device == "dynsimu":  # (see DYNSIMU_CONTACT_KV)
        for held in (contactLF, contactRF):
            held.setVelocityGain(min(DYNSIMU_CONTACT_KV, 0.1 / dt))
            held.setPositionGain(min(DYNSIMU_CONTACT_KV, 0.1 / dt) ** 2 / 4)

    com = momentum = None
    com0 = robot.dynamic.com_at(robot.q0)
    if scenario != "lift_leg_no_com":
        com = MetaTaskDynCom(robot, kp=PUSH_COM_KP if scenario == "push" else COM_KP)
        sot.push(com.task.name)
        momentum = MetaTaskDynMomentum(robot, kv=momentum_damping) if momentum_damping is not None else None
        if momentum is not None and momentum_weight is None:
            sot.push(momentum.task.name)
        left_xy = robot.dynamic.pose_at("contactLF", robot.q0).translation()[:2] + np.array([sum(sole_rectangle()[:2]) / 2, 0.0])
        traj = _com_trajectory(scenario, com0, left_xy)
        if traj is not None:
            ports = trajectory_ports(robot, traj, "com_trajectory")
            connect(ports[0], com.featureDes.GetInputPort("value_in"))
            connect(ports[1], com.featureDes.GetInputPort("velocity_in"))
            connect(ports[2], com.task.GetInputPort("reference_acceleration"))
    posture = MetaTaskDynPosture(robot, kp=25.0)

    foot = None
    if scenario.startswith("lift_leg"):
        foot = MetaTaskDyn6d("RF", robot, "right-foot", "right-sole", kp=400.0)
        p0 = foot.initial_pose().translation()
        t0, t1, height = LIFT
        value, velocity, acceleration = trajectory_ports(robot, hold_move_hold(t0, t1, p0, p0 + [0, 0, height]), "foot_trajectory")
        connect(value, foot.featureDes.GetInputPort("translation_in"))
        connect(velocity, foot.featureDes.GetInputPort("translation_velocity_in"))
        zeros = robot.add(ConstantVectorSource(np.zeros(3)), "foot_zero_angular")
        foot_acc = robot.add(Multiplexer([3, 3]), "foot_reference_acceleration")
        connect(acceleration, foot_acc.get_input_port(0))
        connect(zeros.get_output_port(), foot_acc.get_input_port(1))
        connect(foot_acc.get_output_port(), foot.task.GetInputPort("reference_acceleration"))
    if momentum is not None and momentum_weight is not None:
        sot.push(add_task_weight(robot, "postureAndMomentum", [posture, momentum], [1.0, momentum_weight]))
    else:
        sot.push(posture.task.name)
    if foot is not None:
        release_time, ramp = RELEASE
        attime(release_time, lambda: (sot.push(foot.task.name), sot.up(foot.task.name), sot.rmContact(contactRF, ramp)),
               "rmContact RF (its force ramped to 0), push the foot task above the posture")

    monitor = _add_monitor_and_pushes(robot, scenario, pushes) if device == "physics" else None

    tracer = _add_tracer(robot, dt, com, value if foot is not None else None, monitor)
    visualizer = _add_visualizer(robot, model, meshcat) if meshcat is not None else None
    diagram = builder.Build()
    diagram.set_name("talos_dynamics")
    return DynamicsRun(diagram, robot, tracer, scenario, device, com, foot, monitor, com0, visualizer,
                       (contact, contact_solver) if device == "physics" else None)


def _add_tracer(robot: RobotDyn, dt: float, com: MetaTaskDynCom | None, foot_reference, monitor: ContactMonitor | None
                ) -> Tracer:
    """The trace: the state, the CoM, the torques and wrenches, the references and the feet's forces."""
    tracer = Tracer(robot.builder, dt)
    tracer.add(robot.state_port, "x")
    tracer.add(robot.dynamic.GetOutputPort("com"), "com")
    tracer.add(robot.sot.GetOutputPort("torque"), "torque")
    tracer.add(robot.sot.GetOutputPort("wrenches"), "wrenches")
    if com is not None:
        tracer.add(com.featureDes.GetOutputPort("errorIN"), "com_reference")
    if foot_reference is not None:
        tracer.add(foot_reference, "foot_reference")
    if monitor is not None:
        tracer.add(monitor.GetOutputPort("feet"), "feet")
    return tracer


def _add_monitor_and_pushes(robot: RobotDyn, scenario: str, pushes) -> ContactMonitor:
    """The physics device's contact monitor and the pushes on the torso (``pushes``: see
    :func:`build_diagram`; None: the ``push`` scenario's :data:`PUSHES`, none otherwise)."""
    connect = robot.builder.Connect
    physical = robot.physical
    assert physical is not None  # (the physics device)
    plant = physical.plant
    monitor = robot.add(ContactMonitor(physical))
    connect(plant.get_contact_results_output_port(), monitor.get_input_port())
    if pushes is None and scenario == "push":
        pushes = tuple((start, duration, [force, 0.0, 0.0]) for start, duration, force in PUSHES)
    if pushes:
        mux = robot.add(ExternallyAppliedSpatialForceMultiplexer(len(pushes)), "pushes")
        for i, (start, duration, force) in enumerate(pushes):
            push = robot.add(Push(plant, "torso_2_link", force, start, duration), f"push_{i}")
            connect(push.get_output_port(), mux.get_input_port(i))
        connect(mux.get_output_port(), plant.get_applied_spatial_force_input_port())
    return monitor


def _add_visualizer(robot: RobotDyn, model, meshcat: Meshcat):
    """Meshcat's view of the run: the physics plant's scene graph and its contact forces, or (the
    ``dynsimu`` device) the robot's meshes posed by the state."""
    builder, connect, physical = robot.builder, robot.builder.Connect, robot.physical
    if physical is not None:  # the physics device
        visualizer = MeshcatVisualizer.AddToBuilder(builder, physical.scene_graph, meshcat,
                                                    MeshcatVisualizerParams(publish_period=1 / 60))
        ContactVisualizer.AddToBuilder(builder, physical.plant, meshcat,
                                       ContactVisualizerParams(publish_period=1 / 60, newtons_per_meter=1000))
    else:
        visual = model.with_meshes()
        scene_graph = robot.add(visual.scene_graph, "scene_graph")
        to_pose = robot.add(MultibodyPositionToGeometryPose(visual.plant, input_multibody_state=True), "robot_pose")
        to_pose.visual_model = visual
        connect(robot.state_port, to_pose.get_input_port())
        connect(to_pose.get_output_port(), scene_graph.get_source_pose_port(visual.plant.get_source_id()))
        visualizer = MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, MeshcatVisualizerParams(publish_period=1 / 60))
    meshcat.SetCameraPose(camera_in_world=[1.6, -2.2, 1.3], target_in_world=[0.0, 0.0, 0.6])
    return visualizer


def simulate_ticks(run: DynamicsRun, duration: float, progress: bool = True) -> tuple[Simulator, np.ndarray]:
    """Advance tick by tick (recording if there is a visualizer); returns the simulator and the
    wall time of each tick (s)."""
    from tqdm import tqdm

    simulator = Simulator(run.diagram)
    simulator.Initialize()
    if run.visualizer is not None:
        run.visualizer.StartRecording(False)
    dt = run.robot.dt
    ticks = round(duration / dt)
    times = np.empty(ticks)
    for k in tqdm(range(ticks), disable=not progress, file=sys.stderr, desc=f"{run.scenario}/{run.device}"):
        start = time.perf_counter()
        simulator.AdvanceTo((k + 1) * dt)
        times[k] = time.perf_counter() - start
        state_context = run.robot.state_port.get_system().GetMyContextFromRoot(simulator.get_context())
        if not np.all(np.isfinite(run.robot.state_port.Eval(state_context))):
            times = times[: k + 1]
            break
    return simulator, times


def summarize(run: DynamicsRun, simulator: Simulator, times: np.ndarray, duration: float) -> tuple[dict, dict]:
    trace = run.tracer.data(simulator.get_context())
    robot = run.robot
    nq = robot.model.nq
    t = trace["time"]
    x = trace["x"]
    q = x[:, :nq]
    path = robot.dynamic.trajectory(["contactLF", "contactRF"], np.nan_to_num(q))
    com = trace["com"]
    released_at = RELEASE[0] + RELEASE[1] if run.foot is not None else np.inf
    # Slip of each sole while it is held (xy displacement from its initial pose), at each tick.
    slips = np.zeros(len(t))
    for side, until in (("contactLF", np.inf), ("contactRF", RELEASE[0] if run.foot is not None else np.inf)):
        slip = translation_drift(path[side], 2)
        slips = np.maximum(slips, np.where(t < until, slip, 0.0))
    fall = floating_base_fall(t, x, slips)
    summary: dict = {"scenario": run.scenario, "device": run.device, "duration_s": duration, "ticks": len(times), **fall}
    if run.contact is not None:
        summary["contact"], summary["contact_solver"] = run.contact
    summary["com_drift_m"] = float(point_drift(com).max())
    if "com_reference" in trace:
        error = np.linalg.norm(com - trace["com_reference"], axis=1)
        summary["com_rms_error_m"] = float(np.sqrt(np.mean(error**2)))
        summary["com_max_error_m"] = float(error.max())
    summary["max_foot_slip_m"] = float(slips.max())
    if run.foot is not None and t[-1] >= LIFT[0]:  # (a run stopped before the lift has no foot error)
        p = path["contactRF"][:, :3, 3]
        lifted = t >= LIFT[0]
        error = np.linalg.norm(p - trace["foot_reference"], axis=1)
        summary["foot_rms_error_m"] = float(np.sqrt(np.mean(error[lifted] ** 2)))
        summary["foot_max_error_m"] = float(error[lifted].max())
        summary["foot_height_final_m"] = float(p[-1, 2] - p[0, 2])
    torque_ratio = np.abs(trace["torque"]) / robot.sot.effort  # of the solver's bounds
    summary["effort_scale"] = robot.sot.effort_scale
    summary["max_torque_ratio"] = float(torque_ratio.max())
    summary["torque_at_limit_ticks"] = int(np.count_nonzero(torque_ratio.max(axis=1) >= 1 - 1e-6))  # some |τ| on its limit
    summary["max_torque_ratio_joint"] = robot.model.plant.get_joint_actuator(
        robot.model.plant.GetJointActuatorIndices()[int(np.argmax(torque_ratio.max(axis=0)))]).joint().name()
    summary["tick_us_median"] = float(np.median(times) * 1e6)
    summary["tick_us_p95"] = float(np.percentile(times, 95) * 1e6)
    summary["realtime_factor"] = float(duration / times.sum())
    if "feet" in trace:  # measured by the plant
        feet = trace["feet"]
        mu = FRICTION.dynamic_friction()
        ratios = [friction_ratio(f, np.array([0, 0, 1.0]), mu) for row in feet for f in (row[0:3], row[3:6]) if f[2] > 10.0]
        summary["max_friction_ratio"] = float(max(ratios)) if ratios else 0.0
        settled = [friction_ratio(f, np.array([0, 0, 1.0]), mu) for row in feet[t >= SETTLING_S] for f in (row[0:3], row[3:6])
                   if f[2] > 10.0]  # (at t = 0 the soles land on the plant's contact)
        summary["max_friction_ratio_settled"] = float(max(settled)) if settled else 0.0
        rect = sole_rectangle()
        double = t < released_at
        margins = []
        for k in range(len(t)):
            if not np.all(np.isfinite(feet[k, 6:8])) or k == 0:
                continue
            low, high = support_box(path, ["contactLF", "contactRF"] if double[k] else ["contactLF"], rect)
            cop = feet[k, 6:8]
            margins.append(min((cop - low).min(), (high - cop).min()))
        summary["min_cop_margin_m"] = float(min(margins)) if margins else float("nan")
        if run.foot is not None:
            k = int(np.searchsorted(t, released_at))
            summary["released_force_at_liftoff_n"] = float(feet[min(k, len(t) - 1), 5])
            summary["released_force_before_release_n"] = float(feet[int(np.searchsorted(t, RELEASE[0])) - 1, 5])
        summary["min_normal_force_n"] = float(feet[1:, [2, 5]][t[1:] < min(released_at, t[-1] + 1)].min())
    else:  # the solver's forces (no physics)
        wrenches = trace["wrenches"]
        mu = 0.7
        ratios = [friction_ratio(w[3:], np.array([0, 0, 1.0]), mu) for row in wrenches for w in (row[:6], row[6:]) if w[5] > 10.0]
        summary["max_friction_ratio"] = float(max(ratios)) if ratios else 0.0
        if run.foot is not None:
            summary["released_force_at_liftoff_n"] = float(wrenches[int(np.searchsorted(t, released_at)) - 1, 11])
    trace["tick_s"] = times
    return summary, trace


def effort_fraction(text: str) -> float:
    """``--effort-scale``: a number in (0, 1] (argparse reports anything else as a usage error)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0 < value <= 1:
        raise argparse.ArgumentTypeError(f"must be a number in (0, 1], got {text!r}")
    return value


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/dynamics", duration=5.0)
    parser.add_argument("--scenario", choices=SCENARIOS, default="lift_leg")
    parser.add_argument("--device", choices=["physics", "dynsimu"], default="physics")
    parser.add_argument("--solver", choices=[ACTIVE_SET, *sorted(SOLVERS)], default=ACTIVE_SET,
                        help="how SolverDyn's QP levels are solved (the exact active set, or a Drake solver polished by it)")
    parser.add_argument("--effort-scale", type=effort_fraction, default=1.0,
                        help="the solver's torque bounds as a fraction in (0, 1] of TALOS' effort limits (a derated robot)")
    parser.add_argument("--momentum-damping", type=float, default=None, metavar="KV",
                        help="damp the angular momentum under the CoM task at this rate (1/s; MetaTaskDynMomentum)")
    parser.add_argument("--contact", choices=CONTACT_MODELS, default="hydroelastic",
                        help="physics: the soles' contact model")
    parser.add_argument("--contact-solver", choices=sorted(CONTACT_SOLVERS), default="sap",
                        help="physics: the plant's contact solver (tamsi: faster; sap: converges through any fall)")
    args = parser.parse_args(argv)
    physics_only = options_given(parser, args, ("contact", "contact_solver"), values=True)
    if physics_only and args.device != "physics":
        parser.error(f"{', '.join(physics_only)}: options of --device physics (device='physics'); this run is --device {args.device}")
    meshcat = start(args)
    logging.getLogger("drake").setLevel(logging.WARNING)
    try:
        run = build_diagram(args.scenario, args.device, meshcat, solver=args.solver, effort_scale=args.effort_scale,
                            momentum_damping=args.momentum_damping, contact=args.contact, contact_solver=args.contact_solver)
    except InvalidInput as error:  # (RobotDyn's own check: --contact and --contact-solver are the physics device's)
        parser.error(str(error))
    simulator, times = simulate_ticks(run, args.duration, not args.quiet)
    summary, trace = summarize(run, simulator, times, args.duration)
    args.out.mkdir(parents=True, exist_ok=True)
    dynamics_figure(run.robot, run.com_reference, trace, summary, args.out / "plots.png")
    write_run(args.out, run.diagram, summary, trace, meshcat, run.visualizer, bag=args.bag)
    return summary

