#!/usr/bin/env python3
"""What the collision level costs: the tutorial stack with TALOS' self-collision rows and a table
top, against the same stack without them, in one run (ratios of CPU time, not absolute times).

    python bench/collisions.py                                   # 2000 ticks each, blocks of 100
    python bench/collisions.py --ticks 500
    python bench/collisions.py --placo-python .venv-placo/bin/python   # and placo side by side

The stacks (``sotdrake.collision.reach``) drive the right hand point to the tutorial's target
(0.5, -0.2, 1.0) under SolverKine; they are advanced in alternating blocks so that all see the same
load on the host:

* ``without``: no collision level; ``with``: every pair (887 self pairs from the SRDF, 52 body–table
  pairs); ``with_arm_pairs``: the 143 pairs a user would pick for this reach; ``self_only``: the
  887 self pairs, no table (the side-by-side with placo); ``empty_level``: a collision level whose
  one pair never comes in range, so what remains is what an inequality level costs the solver.

Per tick: the CPU time of ``AdvanceTo`` (median, p90); for ``with``, the pairs queried exactly (the
schedule, ``sotdrake.collision.schedule``) and the pairs in range, and the *floor*: the CPU time of
Drake's exact query of each pair in range alone, timed again after the tick at the tick's
configuration (what any level built on exact distances pays; ``floor_ratio_cpu_median`` is the
ratio it alone would give: the stack without the level, plus it); at the end of each block, at the
``with`` stack's configuration, the cost of one full broad-phase query with the Jacobians of the
pairs in range (what each tick paid without the schedule). ``self_only`` is checked at every tick
with Drake's query on a world of its own (the smallest signed distance, m). Then, on a ``with``
stack of its own, where the tick goes (``breakdown_cpu_us_mean``: the mean CPU time per tick of the
schedule's step, of its support gaps within it, of the rows of the pairs in range and of the
solver's solve, each call wrapped in a timer).

placo (``bench/collisions_placo.py``, run by an interpreter that has placo: this one if it imports
placo, else ``--placo-python``) gets the same robot, self pairs, starting posture and hand path (the
``self_only`` hand point's, tick by tick), feet and CoM held as hard tasks and its
``AvoidSelfCollisionsKinematicsConstraint`` hard with the same margins; its configurations are
checked with the same Drake query. Without placo the comparison is skipped and the JSON says why.
Writes ``bench/results/collisions.json`` (``--out``), and with ``--save`` the committed
``bench/reference/collisions.json`` too.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from output import add_output_arguments, write_json
from pydrake.multibody.tree import JointIndex
from pydrake.systems.analysis import Simulator

from sotdrake.collision import CollisionWorld
from sotdrake.collision.distance import PairTable, minimum_distance, pair_distances
from sotdrake.collision.reach import HAND_OFFSET, build_collision_reach
from sotdrake.collision.schedule import PairSchedule
from sotdrake.collision.task import INFLUENCE_DISTANCE, SAFETY_DISTANCE
from sotdrake.meta_tasks import gotoNd
from sotdrake.robots import load_talos
from sotdrake.robots.loader import urdf_path
from sotdrake.solvers import solver_kine

TARGET = np.array([0.5, -0.2, 1.0])
BLOCK = 100
#: The pair of the ``empty_level`` stack: a foot and the head, never within the influence distance.
FAR_PAIR = ("leg_left_6_link", "head_2_link")


def arm_pairs() -> list[tuple[str, str]]:
    """The pairs a user would pick for this reach: the right forearm, wrist and gripper against the
    torso, the pelvis, the head, the thighs and the table (those the SRDF leaves)."""
    world = CollisionWorld(load_talos("reduced"))
    arm = [link for link in world.links if link.startswith(("arm_right_5", "arm_right_6", "arm_right_7", "wrist_right", "gripper_right"))]
    body = ["torso_1_link", "torso_2_link", "base_link", "head_2_link", "leg_left_1_link", "leg_left_2_link",
            "leg_left_3_link", "leg_right_1_link", "leg_right_2_link", "leg_right_3_link"]
    pairs = [(a, b) for a in arm for b in body if frozenset((a, b)) not in world.disabled | world.adjacent]
    return pairs + [(a, "table") for a in arm]


def _simulator(reach) -> tuple[Simulator, object]:
    simulator = Simulator(reach.diagram)
    context = simulator.get_mutable_context()
    gotoNd(reach.hand, TARGET, "111", (4.9, 0.9, 0.01, 0.9), context=context)
    simulator.Initialize()
    return simulator, context


def _stacks() -> dict:
    return {"without": build_collision_reach(collision=False, table=False),
            "with": build_collision_reach(collision=True, table=True),
            "with_arm_pairs": build_collision_reach(collision=True, table=True, pairs=arm_pairs()),
            "self_only": build_collision_reach(collision=True, table=False),
            "empty_level": build_collision_reach(collision=True, table=False, pairs=[FAR_PAIR])}


def _position(reach, context) -> np.ndarray:
    device = reach.robot.device
    return device.GetOutputPort("state").Eval(device.GetMyContextFromRoot(context)).copy()


def _full_query_us(reach, q: np.ndarray) -> float:
    """CPU time (µs) of one broad-phase query over every pair and the Jacobians of those in range."""
    world = reach.collision.world
    context = world.new_context()
    world.plant.SetPositions(world.plant_context(context), q)
    began = time.thread_time()
    pair_distances(world, context, INFLUENCE_DISTANCE)
    return (time.thread_time() - began) * 1e6


def _exact_queries_us(world: CollisionWorld, context, state) -> float:
    """CPU time (µs) of Drake's exact query of each pair the schedule found in range, at its
    configuration (the floor of the level's tick)."""
    world.plant.SetPositions(world.plant_context(context), state.q)
    query = world.query(context)
    pairs = [(r.id_A, r.id_B) for r in state.in_range]
    began = time.thread_time()
    for a, b in pairs:
        query.ComputeSignedDistancePairClosestPoints(a, b)
    return (time.thread_time() - began) * 1e6


def run_stacks(ticks: int) -> tuple[dict, dict]:
    stacks = _stacks()
    sims = {name: _simulator(reach) for name, reach in stacks.items()}
    cpu: dict[str, list[float]] = {name: [] for name in stacks}
    queried, in_range, full_query_us, hand_path, self_min = [], [], [], [], np.inf
    task = stacks["with"].collision.task
    task_context = task.GetMyContextFromRoot(sims["with"][1])
    floor_context, floor_us = task.world.new_context(), []
    checker, self_only = stacks["self_only"].checker, stacks["self_only"]
    checker_context = checker.new_context()
    dt = stacks["with"].robot.dt
    for start in range(0, ticks, BLOCK):
        for name, (simulator, context) in sims.items():
            for k in range(start + 1, min(start + BLOCK, ticks) + 1):
                began = time.thread_time()
                simulator.AdvanceTo(k * dt)
                cpu[name].append(time.thread_time() - began)
                if name == "with":
                    state = task_context.get_abstract_state(task._schedule_index).get_value().state
                    queried.append(state.queried)
                    in_range.append(len(state.in_range))
                    floor_us.append(_exact_queries_us(task.world, floor_context, state))
                elif name == "self_only":
                    q = _position(self_only, context)
                    self_min = min(self_min, minimum_distance(checker, checker_context, q, INFLUENCE_DISTANCE))
                    hand_path.append(self_only.hand.current_pose(context).translation().tolist())
        full_query_us.append(_full_query_us(stacks["with"], _position(stacks["with"], sims["with"][1])))
    median = {name: float(np.median(t)) for name, t in cpu.items()}
    summary = {
        "ticks": ticks,
        "timing": "CPU time of the thread (time.thread_time), stacks interleaved in blocks of 100 ticks",
        "tick_cpu_us_median": {name: value * 1e6 for name, value in median.items()},
        "tick_cpu_us_p90": {name: float(np.percentile(t, 90)) * 1e6 for name, t in cpu.items()},
        "ratio_cpu_median": median["with"] / median["without"],
        "ratio_cpu_median_arm_pairs": median["with_arm_pairs"] / median["without"],
        "ratio_cpu_median_self_only": median["self_only"] / median["without"],
        "ratio_cpu_median_empty_level": median["empty_level"] / median["without"],
        "floor_us_per_tick_median": float(np.median(floor_us[1:])),
        "floor_ratio_cpu_median": (median["without"] + float(np.median(floor_us[1:])) * 1e-6) / median["without"],
        "self_pairs_checked": len(stacks["with"].collision.world.self_pairs()),
        "pairs_checked": len(task._pair_schedule.pairs) if task._pair_schedule is not None else None,
        "arm_pairs_checked": len(arm_pairs()),
        "pairs_queried_per_tick_median": float(np.median(queried[1:])),
        "pairs_queried_per_tick_max_after_first": int(np.max(queried[1:])),
        "pairs_in_range_median": float(np.median(in_range)),
        "full_query_us_median": float(np.median(full_query_us)),
        "self_only_min_distance_m": float(self_min),
    }
    return summary, {"stack": stacks["self_only"], "hand_path": hand_path}


def breakdown(ticks: int) -> dict:
    """The mean CPU time (µs) per tick of the ``with`` stack's parts over ``ticks`` ticks after the
    first: the schedule's step (the exact queries of the pairs due and the bounds), its support gaps,
    the rows of the pairs in range, and the solver's solve."""
    timed = {"schedule": (PairSchedule, "step"), "gaps": (PairSchedule, "gaps"), "rows": (PairTable, "distances"),
             "solver": (solver_kine, "solve_stack")}
    spent = dict.fromkeys(timed, 0.0)
    originals = {part: getattr(owner, name) for part, (owner, name) in timed.items()}

    def timer(part: str, function):
        def timed_call(*args, **kwargs):
            began = time.thread_time()
            try:
                return function(*args, **kwargs)
            finally:
                spent[part] += time.thread_time() - began
        return timed_call

    reach = build_collision_reach(collision=True, table=True)
    simulator, _ = _simulator(reach)
    dt = reach.robot.dt
    simulator.AdvanceTo(dt)
    try:
        for part, (owner, name) in timed.items():
            setattr(owner, name, timer(part, originals[part]))
        began = time.thread_time()
        for k in range(2, ticks + 1):
            simulator.AdvanceTo(k * dt)
        total = time.thread_time() - began
    finally:
        for part, (owner, name) in timed.items():
            setattr(owner, name, originals[part])
    count = max(ticks - 1, 1)
    return {"tick": total / count * 1e6, **{part: value / count * 1e6 for part, value in spent.items()}}


def _placo_python(option: str | None) -> str | None:
    if option:
        return option
    return sys.executable if importlib.util.find_spec("placo") is not None else None


def _placo_job(reach, hand_path: list, ticks: int) -> dict:
    model = reach.robot.model
    q = np.asarray(reach.robot.device.initial_position)
    plant = model.plant
    joints = {}
    for i in range(plant.num_joints()):
        joint = plant.get_joint(JointIndex(i))
        if joint.type_name() == "revolute":
            joints[joint.name()] = float(q[joint.position_start()])
    return {"urdf": str(urdf_path("talos", "reduced")), "pairs": [list(p) for p in reach.checker.self_pairs()],
            "q0": {"joints": joints, "base_xyz": q[4:7].tolist(), "base_wxyz": q[:4].tolist()},
            "hand_frame": "arm_right_7_link", "hand_offset": list(HAND_OFFSET),
            "feet": ["leg_left_6_link", "leg_right_6_link"], "path": hand_path[:ticks], "dt": reach.robot.dt,
            "safety": SAFETY_DISTANCE, "influence": INFLUENCE_DISTANCE}


def run_placo(python: str | None, side: dict, ticks: int, summary: dict) -> dict:
    """placo's time per tick and the smallest distance (Drake's query on its configurations)."""
    if python is None:
        return {"skipped": "placo is not importable here and no --placo-python was given (placo pins pinocchio "
                           "and numpy versions of its own: install it in a virtual environment of its own)"}
    reach = side["stack"]
    job = _placo_job(reach, side["hand_path"], ticks)
    done = subprocess.run([python, str(HERE / "collisions_placo.py")], input=json.dumps(job), capture_output=True,
                          text=True, check=False)
    if done.returncode != 0:
        return {"failed": done.stderr.strip().splitlines()[-1:] or ["(no message)"]}
    answer = json.loads(done.stdout)
    plant, checker = reach.checker.plant, reach.checker
    context = checker.new_context()
    q = np.asarray(reach.robot.device.initial_position).copy()
    starts = [plant.GetJointByName(name).position_start() for name in answer["joint_names"]]
    smallest = np.inf
    for joints, base in zip(answer["joints"], answer["base_xyz_wxyz"], strict=True):
        q[starts] = joints
        q[4:7], q[:4] = base[:3], base[3:]
        smallest = min(smallest, minimum_distance(checker, context, q, INFLUENCE_DISTANCE))
    tick = float(np.median(answer["cpu_s"])) * 1e6
    return {"ticks": len(answer["cpu_s"]), "pairs": answer["pairs"], "pairs_left_out": answer["pairs_left_out"],
            "tick_cpu_us_median": tick,
            "ratio_to_self_only": tick / summary["tick_cpu_us_median"]["self_only"],
            "min_distance_m": float(smallest),
            "min_distance_placo_own_m": float(np.min(answer["placo_min_distance"]))}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--ticks", type=int, default=2000)
    parser.add_argument("--placo-python", default=None, help="an interpreter that imports placo")
    parser.add_argument("--placo-ticks", type=int, default=200, help="ticks of the hand path given to placo")
    add_output_arguments(parser, "collisions.json")
    args = parser.parse_args(argv)
    summary, side = run_stacks(args.ticks)
    summary["breakdown_cpu_us_mean"] = breakdown(args.ticks)
    summary["placo"] = run_placo(_placo_python(args.placo_python), side, args.placo_ticks, summary)
    print(json.dumps(summary, indent=1))
    write_json(summary, args.out, save=args.save, indent=1)
    return summary


if __name__ == "__main__":
    main()
