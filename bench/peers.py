"""The peers on the benchmark scenario: pink (weighted differential IK over Pinocchio, daqp) and
placo (C++ core; hard and soft priorities). Each returns its per-tick times and its accuracy.

pink has no strict priorities: the feet and the CoM get a weight 1000× the hand's. placo's feet are
"hard" (equality constraints), CoM and hand "soft" (weights 100 and 1). Both integrate their own
configuration, as a kinematic SoT device does.
"""

from __future__ import annotations

import time
from collections.abc import Generator

import numpy as np
from scenario import (
    DT,
    FEET,
    GAIN_COM,
    GAIN_FEET,
    GAIN_HAND,
    HAND_FRAME,
    TARGET,
    pinocchio_half_sitting,
    urdf_file,
    urdf_text,
)


def _version(distribution: str) -> str:
    """The installed version of a PyPI distribution (placo has no ``__version__``)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(distribution)
    except PackageNotFoundError:
        return "(version unknown)"


def _accuracy(hand, feet, feet0, com, com0) -> dict:
    return {
        "hand_error_m": float(np.linalg.norm(hand - TARGET)),
        "max_foot_drift_m": float(max(np.linalg.norm(f - f0) for f, f0 in zip(feet, feet0, strict=False))),
        "max_com_drift_m": float(np.linalg.norm(com - com0)),
    }


def finish(run: Generator[None, None, dict]) -> dict:
    """Run a tick generator (:func:`pink_ticks`, …) to its end: its result."""
    while True:
        try:
            next(run)
        except StopIteration as done:
            return done.value


def run_pink(ticks: int, warmup: int, solver: str = "daqp") -> dict:
    return finish(pink_ticks(ticks, warmup, solver))


def run_placo(ticks: int, warmup: int) -> dict:
    return finish(placo_ticks(ticks, warmup))


def pink_ticks(ticks: int, warmup: int, solver: str = "daqp") -> Generator[None, None, dict]:
    """pink on the scenario, one tick per ``next`` (so that runs can be interleaved); returns the
    per-tick times (after ``warmup``) and the accuracy. Imports pink on the first ``next``."""
    import pink
    import pinocchio as pin
    from pink.limits import ConfigurationLimit, VelocityLimit
    from pink.tasks import ComTask, FrameTask

    model = pin.buildModelFromXML(urdf_text(), pin.JointModelFreeFlyer())
    data = model.createData()
    configuration = pink.Configuration(model, data, pinocchio_half_sitting(model))
    feet = [FrameTask(f, position_cost=1000.0, orientation_cost=1000.0, gain=GAIN_FEET * DT) for f in FEET]
    for task in feet:
        task.set_target_from_configuration(configuration)
    com = ComTask(cost=1000.0, gain=GAIN_COM * DT)
    com.set_target_from_configuration(configuration)
    hand = FrameTask(HAND_FRAME, position_cost=1.0, orientation_cost=0.0, gain=GAIN_HAND * DT)
    target = configuration.get_transform_frame_to_world(HAND_FRAME).copy()
    target.translation = TARGET
    hand.set_target(target)
    tasks = [*feet, com, hand]
    limits = [ConfigurationLimit(model), VelocityLimit(model)]
    feet0 = [configuration.get_transform_frame_to_world(f).translation.copy() for f in FEET]
    com0 = pin.centerOfMass(model, data, configuration.q).copy()
    times, cpu, drift = [], [], 0.0
    for k in range(warmup + ticks):
        start, start_cpu = time.perf_counter(), time.thread_time()
        v = pink.solve_ik(configuration, tasks, DT, solver=solver, limits=limits, safety_break=False)
        configuration.integrate_inplace(v, DT)
        times.append(time.perf_counter() - start)
        cpu.append(time.thread_time() - start_cpu)
        if k % 10 == 0:  # outside the timed region
            drift = max(drift, max(np.linalg.norm(configuration.get_transform_frame_to_world(f).translation - f0)
                                   for f, f0 in zip(FEET, feet0, strict=False)))
        yield
    accuracy = _accuracy(configuration.get_transform_frame_to_world(HAND_FRAME).translation,
                         [configuration.get_transform_frame_to_world(f).translation for f in FEET], feet0,
                         pin.centerOfMass(model, data, configuration.q), com0)
    accuracy["max_foot_drift_m"] = max(accuracy["max_foot_drift_m"], drift)
    return {"times_s": np.array(times[warmup:]), "cpu_s": np.array(cpu[warmup:]), "accuracy": accuracy,
            "version": _version("pin-pink"), "qp_solver": solver}


def placo_ticks(ticks: int, warmup: int) -> Generator[None, None, dict]:
    """placo on the scenario, one tick per ``next`` (see :func:`pink_ticks`)."""
    import placo

    robot = placo.RobotWrapper(str(urdf_file()), placo.Flags.ignore_collisions)
    robot.state.q = pinocchio_half_sitting(robot.model)
    robot.update_kinematics()
    solver = placo.KinematicsSolver(robot)
    solver.mask_fbase(False)
    solver.enable_joint_limits(True)
    solver.enable_velocity_limits(True)
    solver.dt = DT
    feet0 = []
    for frame in FEET:
        T = robot.get_T_world_frame(frame)
        feet0.append(T[:3, 3].copy())
        solver.add_frame_task(frame, T).configure(frame, "hard", 1.0)
    com0 = robot.com_world().copy()
    solver.add_com_task(com0).configure("com", "soft", 100.0)
    hand = solver.add_position_task(HAND_FRAME, TARGET)
    hand.configure("hand", "soft", 1.0)
    times, cpu, drift = [], [], 0.0
    for k in range(warmup + ticks):
        start, start_cpu = time.perf_counter(), time.thread_time()
        solver.solve(True)
        robot.update_kinematics()
        times.append(time.perf_counter() - start)
        cpu.append(time.thread_time() - start_cpu)
        if k % 10 == 0:
            drift = max(drift, max(np.linalg.norm(robot.get_T_world_frame(f)[:3, 3] - f0) for f, f0 in zip(FEET, feet0, strict=False)))
        yield
    accuracy = _accuracy(robot.get_T_world_frame(HAND_FRAME)[:3, 3], [robot.get_T_world_frame(f)[:3, 3] for f in FEET],
                         feet0, robot.com_world(), com0)
    accuracy["max_foot_drift_m"] = max(accuracy["max_foot_drift_m"], drift)
    return {"times_s": np.array(times[warmup:]), "cpu_s": np.array(cpu[warmup:]), "accuracy": accuracy, "version": _version("placo"),
            "note": "placo's KinematicsSolver closes each task's whole error at every step (no task gain)"}
