#!/usr/bin/env python3
"""The sot-talos ``test.py`` over ROS 2: drives ``talos_appli.py --ros`` from another process.

As the seed: wait for the ``run_command`` and ``start_dynamic_graph`` services, send ``appli.py``
line by line, start the dynamic graph, then move the hand with three ``run_command`` calls::

    python diagrams/talos_appli.py --ros --no-meshcat --out out/ros &   # the SoT side
    python diagrams/ros_test.py                                        # this script

Where it differs: the control graph is built by the diagram (Drake connects ports before a run),
so the appli lines set what ``appli.py`` sets on it (frames, gains, ``keep()``, the stack) in the
live channel's grammar; the seed's ``target = (0.5,-0.2,1.0)`` is written into the ``gotoNd`` call
(the grammar has no assignment); ``--interactive`` waits for Enter where the seed's ``raw_input``
did. ``--settle S`` waits S s of simulated time after the hand is pushed and ``--stop`` then stops
the run (which writes its files).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from sotdrake import SotError

#: The seed's appli.py, in the live channel's grammar (the graph itself is the diagram's).
APPLI = """\
# --- the right hand: MetaTaskKine6d('rh', ...), opmodif (0.1, 0, 0): built by the diagram
taskRH.feature.frame('desired')
# --- STATIC COM (if not walking)
taskCom.keep()
taskCom.gain.setConstant(10)
# --- CONTACTS
contactLF.feature.frame('desired')
contactLF.gain.setConstant(10)
contactLF.keep()
contactRF.feature.frame('desired')
contactRF.gain.setConstant(10)
contactRF.keep()
# --- the stack
sot.clear()
sot.push('taskcontactRF')
sot.push('taskcontactLF')
sot.push('taskcom')
"""

#: The seed's calls that move the hand.
HAND = (
    "gotoNd(taskRH, (0.5, -0.2, 1.0), '111', (4.9, 0.9, 0.01, 0.9))",
    "sot.push('taskrh')",
)


def launch_script(client, code: list[str], title: str, interactive: bool) -> None:
    """The seed's ``launchScript``: every line that is not empty or a comment, one call each."""
    if interactive:
        input(f"{title}: press Enter")
    print(f"{title}", flush=True)
    for line in code:
        if line.strip() and not line.lstrip().startswith("#"):
            answer = client.command(line)
            print(f"  {line}\n    -> {answer.get('answer') if answer['ok'] else 'ERROR ' + answer['error']}", flush=True)
            if not answer["ok"]:
                raise SystemExit(f"run_command refused {line!r}: {answer['error']}")
    print(f"...done with {title}", flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--appli", type=Path, help="a file of commands to send instead of the built-in appli lines")
    parser.add_argument("--timeout", type=float, default=120.0, help="longest wait for a service or an answer (s)")
    parser.add_argument("--interactive", action="store_true", help="wait for Enter between steps, as the seed")
    parser.add_argument("--settle", type=float, default=None, help="then wait this many simulated s")
    parser.add_argument("--stop", action="store_true", help="then stop the run (it writes its files)")
    args = parser.parse_args(argv)
    # (1e6 s: the client's MAX_TIMEOUT_S, checked here before ROS is imported)
    if not 0 < args.timeout <= 1e6 or (args.settle is not None and not 0 <= args.settle < float("inf")):
        parser.error(f"--timeout must be a number in (0, 1e6] (s) and --settle ≥ 0, got {args.timeout}, {args.settle}")
    if args.appli is not None and not args.appli.is_file():
        parser.error(f"--appli {args.appli}: no such file")

    import sotdrake.ros  # the optional ros2 extra

    print("Waiting for run_command and start_dynamic_graph", flush=True)
    client = sotdrake.ros.wait_for_services(args.timeout)
    print("...ok", flush=True)
    code = (args.appli.read_text() if args.appli else APPLI).split("\n")
    launch_script(client, code, "initialize SoT", args.interactive)
    if args.interactive:
        input("Wait before starting the dynamic graph")
    client.start()
    print("dynamic graph started", flush=True)
    if args.interactive:
        input("Wait before moving the hand")
    launch_script(client, list(HAND), "move the hand", False)
    pushed = float(client.command("time()")["answer"])
    print(f"hand pushed at t = {pushed:.3f} s", flush=True)
    if args.settle is not None:
        deadline = time.monotonic() + max(args.timeout, 60 * args.settle)
        while float(client.command("time()")["answer"]) < pushed + args.settle:
            if time.monotonic() > deadline:
                raise SystemExit(f"the run did not reach t = {pushed + args.settle:.3f} s")
            time.sleep(0.1)
        error = client.command("signal(taskrh, 'error_norm')")["answer"]
        print(f"hand error: {error}", flush=True)
    if args.stop:
        print(client.command("stop()")["answer"], flush=True)
    client.close()
    sotdrake.ros.shutdown()
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except SotError as error:  # no service, no answer in time
        sys.exit(f"ros_test.py: {error}")
