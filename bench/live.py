#!/usr/bin/env python3
"""A live run under a burst of commands: commands per second, ticks missed, real time kept.

    python bench/live.py                    # talos_appli --live at rate 1, hand pushed, 10 000 commands
    python bench/live.py --rate 0.25 --no-meshcat

Starts ``diagrams/talos_appli.py --live`` in its own process, pushes the hand task (four tasks in
the stack, as in the tutorial), waits 3 s (the idle reference), sends the burst from this process
(a quarter accepted queries, three quarters refused: by the API, by the grammar, by the stack),
prints the figures of :func:`sotdrake.live.burst.measure_burst` as JSON (and writes them to ``--out``,
default ``bench/results/live.json``, ignored by git) and stops the run.
Before that, in this process, the cost of one command in the simulation thread (parse, check,
apply, answer text) for a few kinds (µs, mean of repeated calls).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

sys.path.insert(0, str(ROOT / "bench"))

from output import add_output_arguments, write_json

from sotdrake.live.burst import measure_burst
from sotdrake.live.shell import Client

COMMANDS = ["sot.stack()", "gainrh.setConstant(-1)", "__import__('os').system('touch X')", "sot.up('taskcontactRF')"]


COSTED = COMMANDS + ["gotoNd(taskRH, (0.5, -0.2, 1.0), '111', (4.9, 0.9, 0.01, 0.9))", "displaySignals(sot)"]


def command_costs(repeat: int = 1000) -> dict[str, float]:
    """µs per command through ``CommandServer.handle`` on the tutorial's diagram."""
    from pydrake.systems.analysis import Simulator

    from sotdrake.live.server import CommandServer
    from sotdrake.live.vocabulary import Vocabulary
    from sotdrake.scenarios import talos_appli

    appli = talos_appli.build_diagram(push_time=None)
    simulator = Simulator(appli.diagram)
    simulator.Initialize()
    server = CommandServer(Vocabulary(appli.diagram, appli), "bench")
    costs = {}
    try:
        for text in COSTED:
            n = repeat if "display" not in text else max(1, repeat // 20)
            start = time.perf_counter()
            for _ in range(n):
                server.handle(text.encode(), simulator.get_mutable_context())
            costs[text] = round(1e6 * (time.perf_counter() - start) / n, 1)
    finally:
        server.close()
    return costs


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rate", type=float, default=1.0)
    parser.add_argument("--count", type=int, default=10_000)
    parser.add_argument("--no-meshcat", action="store_true")
    add_output_arguments(parser, "live.json")
    args = parser.parse_args(argv)
    costs = command_costs()
    with tempfile.TemporaryDirectory() as work:
        out = Path(work) / "out"
        command = [sys.executable, str(ROOT / "diagrams" / "talos_appli.py"), "--live", "--no-push",
                   "--out", str(out), "--rate", str(args.rate)] + (["--no-meshcat"] if args.no_meshcat else [])
        env = dict(os.environ, PYTHONPATH=str(ROOT), XDG_RUNTIME_DIR=work)
        process = subprocess.Popen(command, cwd=work, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            while not (out / "live.json").exists():
                if process.poll() is not None:
                    raise SystemExit("the live run did not start")
                time.sleep(0.2)
            with Client(out / "live.json", timeout=60) as client:
                assert client.command("sot.push('taskrh')")["ok"]
                figures, _ = measure_burst(client, COMMANDS, args.count, args.rate, 1e-3)
            figures["meshcat"] = not args.no_meshcat
            figures["command_cost_us"] = costs
            figures["load_average"] = os.getloadavg()
        finally:
            process.send_signal(signal.SIGINT)
            process.wait(120)
    print(json.dumps(figures, indent=2))
    write_json(figures, args.out, args.save)
    return figures


if __name__ == "__main__":
    main()
