#!/usr/bin/env python3
"""placo's side of ``bench/collisions.py``: the same TALOS, self-collision pairs and hand path under
placo's ``KinematicsSolver`` with its ``AvoidSelfCollisionsKinematicsConstraint`` (hard).

Run by ``bench/collisions.py`` with an interpreter that has placo (placo pins its own pinocchio and
numpy, so it usually lives in a virtual environment of its own); it reads one JSON job on stdin and
writes one JSON answer on stdout. It imports nothing from sotdrake.

The job: ``urdf`` (the TALOS URDF file; ``package://`` paths are looked up above it), ``pairs``
(link-name pairs), ``q0`` (joint angles by name, and the base pose: ``base_xyz``,
``base_wxyz``), ``hand_frame``/``hand_offset`` (the hand point: a point fixed in that link),
``feet`` (the two ankle links, held), ``path`` (the hand point's target at each tick, m, world),
``dt`` (s), ``safety`` and ``influence`` (m, placo's margin and trigger). The answer: the CPU time
of each tick (``solve`` and the kinematics update), the joint angles and base pose at each tick
(for the caller's own distance check), and placo's own smallest distance over the pairs at each tick.
"""

from __future__ import annotations

import json
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import placo


def _robot(job: dict, folder: Path) -> placo.RobotWrapper:
    urdf = Path(job["urdf"])
    text = urdf.read_text()
    package = re.search(r"package://([^/]+)/", text)
    if package is not None:  # the folder above the package's, found from the URDF's own place
        root = next(p for p in urdf.parents if (p / package.group(1)).is_dir())
        text = text.replace("package://", f"{root}/")
    hand = (f'<link name="bench_hand_point"/><joint name="bench_hand_point_joint" type="fixed">'
            f'<parent link="{job["hand_frame"]}"/><child link="bench_hand_point"/>'
            f'<origin xyz="{" ".join(map(str, job["hand_offset"]))}" rpy="0 0 0"/></joint></robot>')
    text = text.replace("</robot>", hand)
    (folder / "robot.urdf").write_text(text)
    (folder / "collisions.json").write_text(json.dumps(job["pairs"]))
    return placo.RobotWrapper(str(folder / "robot.urdf"))


def _pose(xyz: list, wxyz: list) -> np.ndarray:
    w, x, y, z = wxyz
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, xyz
    return T


def _wxyz(R: np.ndarray) -> list[float]:
    w = 0.5 * np.sqrt(max(1e-12, 1 + np.trace(R)))
    return [w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)]


def run(job: dict) -> dict:
    with tempfile.TemporaryDirectory() as folder:
        robot = _robot(job, Path(folder))
        robot.load_collision_pairs(str(Path(folder) / "collisions.json"))
    for name, angle in job["q0"]["joints"].items():
        robot.set_joint(name, angle)
    robot.set_T_world_fbase(_pose(job["q0"]["base_xyz"], job["q0"]["base_wxyz"]))
    robot.update_kinematics()
    # A pair already closer than the margin at the start (placo measures the meshes themselves, not
    # their hulls; the gripper's rigidly joined links) would make the hard constraint infeasible.
    geometries = robot.collision_model.geometryObjects
    link = [g.name.rsplit("_", 1)[0] for g in geometries]  # pinocchio names them <link>_<n>
    inside = {frozenset((link[d.objA], link[d.objB])) for d in robot.distances() if d.min_distance < job["safety"]}
    kept = [pair for pair in job["pairs"] if frozenset(pair) not in inside]
    with tempfile.TemporaryDirectory() as folder:
        (Path(folder) / "collisions.json").write_text(json.dumps(kept))
        robot.load_collision_pairs(str(Path(folder) / "collisions.json"))
    solver = placo.KinematicsSolver(robot)
    solver.mask_fbase(False)
    solver.dt = job["dt"]
    solver.enable_velocity_limits(True)
    for foot in job["feet"]:
        solver.add_frame_task(foot, robot.get_T_world_frame(foot)).configure(foot, "hard", 1.0)
    solver.add_com_task(robot.com_world()).configure("com", "hard", 1.0)
    hand = solver.add_position_task("bench_hand_point", robot.get_T_world_frame("bench_hand_point")[:3, 3])
    hand.configure("hand", "soft", 1.0)
    solver.add_regularization_task(1e-6)
    constraint = solver.add_avoid_self_collisions_constraint()
    constraint.self_collisions_margin = job["safety"]
    constraint.self_collisions_trigger = job["influence"]
    constraint.configure("self_collisions", "hard")
    names = list(job["q0"]["joints"])
    cpu, joints, bases, placo_min = [], [], [], []
    for target in job["path"]:
        hand.target_world = np.asarray(target)
        began = time.thread_time()
        solver.solve(True)
        robot.update_kinematics()
        cpu.append(time.thread_time() - began)
        joints.append([robot.get_joint(name) for name in names])
        T = robot.get_T_world_fbase()
        bases.append([*T[:3, 3].tolist(), *_wxyz(T[:3, :3])])
        distances = robot.distances()
        placo_min.append(min((d.min_distance for d in distances), default=float("inf")))
    return {"pairs": len(kept), "pairs_left_out": sorted(sorted(pair) for pair in inside), "cpu_s": cpu,
            "joint_names": names, "joints": joints, "base_xyz_wxyz": bases, "placo_min_distance": placo_min}


if __name__ == "__main__":
    answer = run(json.load(sys.stdin))
    sys.stdout.write(json.dumps(answer))
    sys.stdout.flush()
    os._exit(0)  # (skip the interpreter's teardown of placo's objects)
