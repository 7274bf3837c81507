"""The command-line arguments of a sweep script (``diagrams/reach_map.py``, ``push_map.py``)."""

from __future__ import annotations

import argparse

from .engines import ENGINES


def add_sweep_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add ``--engine``, ``--address`` and ``--num-cpus`` to ``parser``."""
    group = parser.add_argument_group("sweep")
    group.add_argument("--engine", choices=ENGINES, default="local",
                       help="local: in this process, one core; ray: a Ray runtime (needs the [sweep] extra)")
    group.add_argument("--address", default=None,
                       help="with --engine ray: join this Ray cluster ('auto', 'ray://head:10001') "
                            "instead of starting a local runtime")
    group.add_argument("--num-cpus", type=int, default=None,
                       help="with --engine ray and no --address: CPUs of the local runtime (default: all)")
    return parser


def engine_options(args: argparse.Namespace) -> dict:
    """The keyword arguments of :func:`run_sweep` taken from ``args``. An option of another engine
    (``--address`` or ``--num-cpus`` without ``--engine ray``, ``--num-cpus`` with ``--address``:
    the cluster has its own CPUs) or ``--num-cpus`` below 1 is refused, not ignored: a
    ``SystemExit`` naming it (:func:`sotdrake.simulation.run_script` ends the script with it)."""
    if args.address is not None and args.engine != "ray":
        raise SystemExit("--address needs --engine ray")
    if args.num_cpus is not None:
        if args.engine != "ray":
            raise SystemExit(f"--num-cpus needs --engine ray (--engine {args.engine} runs in this process, on one core)")
        if args.address is not None:
            raise SystemExit("--num-cpus is for the local Ray runtime: a cluster joined with --address has its own CPUs")
        if args.num_cpus < 1:
            raise SystemExit(f"--num-cpus must be ≥ 1, got {args.num_cpus}")
    return {"engine": args.engine, "address": args.address, "num_cpus": args.num_cpus}
