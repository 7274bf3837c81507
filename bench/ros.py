#!/usr/bin/env python3
"""The cost of ROS 2 publishing in a run: µs per message and the real-time factor, with and without.

    .venv/bin/python bench/ros.py                    # 2 s of the tutorial's stack, three variants
    .venv/bin/python bench/ros.py --duration 5 --out bench/results/ros.json

In one process, one after the other on the same stack (both feet, CoM, right hand; basic ``SOT``,
1 kHz): no publisher; ``add_ros_publisher`` every 100 ticks (the seed's ``addDownsampledSignal``);
every tick. A node in this process (its own rclpy context) subscribes to both topics, so the
messages are delivered, not dropped. Printed as JSON: per variant the wall time, the real-time
factor (simulated s / wall s), messages published and received, and the mean µs per publish
(message built and handed to DDS) of ``/sot_control/state`` and ``/joint_states``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


def build(every: int | None):
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake import TALOS_GRIPPERS, MetaTaskKine6d, MetaTaskKineCom, add_sot, gotoNd, talos

    builder = DiagramBuilder()
    robot = talos(builder)
    hand = MetaTaskKine6d("rh", robot, "rh", robot.OperationalPointsMap["right-wrist"])
    com = MetaTaskKineCom(robot)
    com.keep()
    com.gain.setConstant(10)
    feet = []
    for name, point in (("contactLF", "left-ankle"), ("contactRF", "right-ankle")):
        foot = MetaTaskKine6d(name, robot, name[-2:], robot.OperationalPointsMap[point])
        foot.feature.frame("desired")
        foot.gain.setConstant(10)
        foot.keep()
        feet.append(foot)
    sot = add_sot(robot, "sot")
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))
    for task in (feet[1], feet[0], com, hand):
        sot.push(task.task.name)
    gotoNd(hand, (0.5, -0.2, 1.0), "111", (4.9, 0.9, 0.01, 0.9))
    publishers = None
    if every is not None:
        from sotdrake.ros import add_ros_publisher

        publishers = add_ros_publisher(robot, every=every)
    return builder.Build(), publishers


def run(every: int | None, duration: float, received: dict) -> dict:
    from pydrake.systems.analysis import Simulator

    diagram, publishers = build(every)
    if publishers is not None:  # the listener matched before the first message
        deadline = time.monotonic() + 120
        while publishers.state.signals["state"].publisher.get_subscription_count() == 0:
            if time.monotonic() > deadline:
                raise SystemExit("the listener did not match within 120 s")
            time.sleep(0.05)
    simulator = Simulator(diagram)
    simulator.Initialize()
    before = dict(received)
    start = time.perf_counter()
    simulator.AdvanceTo(duration)
    wall = time.perf_counter() - start
    result = {"every_ticks": every, "wall_s": wall, "realtime_factor": duration / wall}
    if publishers is not None:
        time.sleep(1.0)  # the last messages in flight
        for key, system in (("state", publishers.state), ("joint_states", publishers.joint_states)):
            result[f"{key}_published"] = system.published
            result[f"{key}_received"] = received[key] - before[key]
            result[f"{key}_publish_us"] = 1e6 * system.publish_seconds / max(system.published, 1)
    return result


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration", type=float, default=2.0, help="simulated seconds per variant")
    parser.add_argument("--out", type=Path, help="also write the JSON there")
    args = parser.parse_args(argv)

    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    from sotdrake.ros import RosNode, shutdown

    listener = RosNode("bench_listener")
    received = {"state": 0, "joint_states": 0}

    def count(key):
        def on_message(_message) -> None:
            received[key] += 1
        return on_message

    listener.node.create_subscription(Float64MultiArray, "/sot_control/state", count("state"), 10_000)
    listener.node.create_subscription(JointState, "/joint_states", count("joint_states"), 10_000)
    run(None, 0.05, received)  # warm up: imports, numba's compilation
    results = {"duration_s": args.duration, "variants": [run(every, args.duration, received) for every in (None, 100, 1)]}
    listener.close()
    shutdown()
    text = json.dumps(results, indent=2)
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")
    return results


if __name__ == "__main__":
    main()
