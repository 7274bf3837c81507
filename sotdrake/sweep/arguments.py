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
    """The keyword arguments of :func:`run_sweep` taken from ``args``."""
    if args.address is not None and args.engine != "ray":
        raise SystemExit("--address needs --engine ray")
    return {"engine": args.engine, "address": args.address, "num_cpus": args.num_cpus}
