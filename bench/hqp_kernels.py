"""The random-stack sweep under several CPU kernels: the contract holds whatever the round-off.

The same code gives other round-off on another CPU through three doors: OpenBLAS's kernel
(``OPENBLAS_CORETYPE``), numpy's SIMD dispatch (``NPY_DISABLE_CPU_FEATURES``) and numba's target
(``NUMBA_CPU_NAME``). This script solves the random stacks of ``tests/hqp_stacks.py`` (seeds
``--first`` to ``--first + --count``, as the tests do: one solver per size, reused) once per kernel,
each kernel in its own process (run side by side) with its own numba cache, and checks on each stack the hierarchical
QP's contract:

* no failure, ``x`` finite, the bounds held exactly;
* strictness: the slack norms of levels ``0..k`` equal those of the first ``k + 1`` levels solved
  alone, to ``1e-6`` relative + ``1e-9`` + the round-off of evaluating a level's residual
  (``1e-12 ‖A_k‖ ‖x‖``), the tests' tolerance, + what the solver's feasibility tolerance lets a
  held row move (``1e-9`` on the row scaled to unit norm, relative above 1: ``1e-9 max(‖a_i‖, |bound_i|)``
  in the row's units, the norm of those over the level's rows).

It then counts the stacks whose answering path (each level's solver and the fallbacks taken)
differs between kernels, and checks that each such stack meets the contract under every kernel.
Prints a table and writes ``--out`` (or ``--json``; default ``bench/results/hqp_kernels.json``, ignored by
git; ``--save``: also the committed ``bench/reference/<its name>``)::

    .venv/bin/python bench/hqp_kernels.py --count 40000
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from output import add_output_arguments, write_json

#: The kernels compared: the host's own, and two that stand for other x86-64 CPUs.
KERNELS: dict[str, dict[str, str]] = {
    "host": {},
    "avx2": {  # an AVX2 machine without AVX-512 (e.g. AMD EPYC Zen 2/3, Intel Haswell to Comet Lake)
        "OPENBLAS_CORETYPE": "Haswell",
        "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
        "NUMBA_CPU_NAME": "haswell",
    },
    "generic": {  # the oldest x86-64: SSE2/SSE3 kernels, no FMA anywhere
        "OPENBLAS_CORETYPE": "Prescott",
        "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR",
        "NUMBA_CPU_NAME": "generic",
    },
}


def same_norms(a: np.ndarray, b: np.ndarray, floor: np.ndarray) -> bool:
    return bool(np.all(np.abs(a - b) <= 1e-6 * np.maximum(np.abs(a), np.abs(b)) + 1e-9 + floor[: len(a)]))


def held_row_tolerance(level, tolerance: float = 1e-9) -> float:
    """How far the solver's feasibility tolerance lets the level's rows move once held: the norm of
    ``tolerance · max(‖a_i‖, |bound_i|)`` over its rows (the tolerance on the row scaled to unit norm,
    relative above 1, in the row's units; the larger finite side of each)."""
    sides = np.where(np.isfinite(level.lower), np.abs(level.lower), 0.0)
    sides = np.maximum(sides, np.where(np.isfinite(level.upper), np.abs(level.upper), 0.0))
    return float(np.linalg.norm(tolerance * np.maximum(np.linalg.norm(level.A, axis=1), sides)))


def sweep(first: int, count: int, reuse: bool = False) -> list[dict]:
    """Each stack's outcome: ``seed``, ``ok`` (the contract held), ``why`` (if not), ``path``."""
    from sotdrake.exceptions import SolverError
    from sotdrake.hqp.solve import HierarchicalQP
    from tests.hqp_stacks import random_stack

    solvers: dict[int, HierarchicalQP] = {}
    out = []
    for seed in range(first, first + count):
        n, levels, x_lower, x_upper = random_stack(np.random.default_rng(seed))
        if not reuse:
            solvers.clear()
        hqp = solvers.setdefault(n, HierarchicalQP(n))
        prefix = solvers.setdefault(-n, HierarchicalQP(n, regularize=False))
        record: dict = {"seed": seed, "ok": True, "why": "", "path": ""}
        try:
            result = hqp.solve(levels, x_lower, x_upper)
            record["path"] = "|".join(result.level_solvers) + "#" + ";".join(f.split(":")[0] + ":" + f.split(":")[1][:40]
                                                                             for f in result.fallbacks if ":" in f)
            if not np.all(np.isfinite(result.x)):
                record.update(ok=False, why="not finite")
            elif not (np.all(result.x >= x_lower) and np.all(result.x <= x_upper)):
                record.update(ok=False, why="bounds")
            else:
                for k in range(len(levels) - 1):
                    alone = prefix.solve(levels[: k + 1], x_lower, x_upper)
                    norms = np.linalg.norm
                    floor = np.array([1e-12 * norms(level.A) * max(norms(result.x), norms(alone.x)) + held_row_tolerance(level)
                                      for level in levels])
                    if not same_norms(result.slack_norms[: k + 1], alone.slack_norms, floor):
                        record.update(ok=False, why=f"strictness at level {k}")
                        break
        except SolverError as error:
            record.update(ok=False, why=f"failure: {str(error)[:200]}")
        out.append(record)
        if (seed - first + 1) % 1000 == 0:
            print(f"  {os.environ.get('SWEEP_KERNEL', '')}: {seed - first + 1} of {count} stacks", file=sys.stderr, flush=True)
    return out


def start_kernel(name: str, first: int, count: int, cache: Path, sink: Path, reuse: bool) -> subprocess.Popen:
    """The sweep under kernel ``name`` in its own process (its own numba cache), writing ``sink``."""
    env = dict(os.environ, **KERNELS[name], NUMBA_CACHE_DIR=str(cache / name), PYTHONPATH=str(ROOT), SWEEP_KERNEL=name)
    return subprocess.Popen([sys.executable, __file__, "--worker", str(sink), "--first", str(first), "--count", str(count),
                             *(["--reuse"] if reuse else [])], env=env, cwd=ROOT)


def merge(paths: list[Path], out: Path) -> int:
    """One summary of runs over consecutive seed ranges (e.g. a long sweep run in parts)."""
    parts = sorted((json.loads(path.read_text()) for path in paths), key=lambda part: part["first_seed"])
    for before, after in itertools.pairwise(parts):
        if before["first_seed"] + before["stacks"] != after["first_seed"] or before["kernels"] != after["kernels"]:
            raise SystemExit("the runs to merge must cover consecutive seeds with the same kernels")
    names = list(parts[0]["kernels"])
    summary = {
        "first_seed": parts[0]["first_seed"], "stacks": sum(part["stacks"] for part in parts),
        "reuse": parts[0]["reuse"], "kernels": parts[0]["kernels"],
        "failed": {name: sum(part["failed"][name] for part in parts) for name in names},
        "failures": {name: [r for part in parts for r in part["failures"][name]][:20] for name in names},
        "paths_differ": sum(part["paths_differ"] for part in parts),
        "paths_differ_and_contract_missed": sum(part["paths_differ_and_contract_missed"] for part in parts),
        "paths_differ_seeds": [seed for part in parts for seed in part["paths_differ_seeds"]][:50],
        "seconds": {name: round(sum(part["seconds"][name] for part in parts), 1) for name in names},
    }
    out.write_text(json.dumps(summary, indent=1) + "\n")
    print(f"{summary['stacks']} stacks from seed {summary['first_seed']}: contract missed {summary['failed']}, "
          f"paths differ on {summary['paths_differ']}")
    return 1 if any(summary["failed"].values()) else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--first", type=int, default=100_000, help="the first seed (default 100000)")
    parser.add_argument("--count", type=int, default=2000, help="how many stacks (default 2000)")
    parser.add_argument("--kernels", default=",".join(KERNELS), help=f"among {', '.join(KERNELS)}")
    parser.add_argument("--reuse", action="store_true", help="one solver per size, reused from stack to stack (warm)")
    parser.add_argument("--cache", type=Path, help="where each kernel's numba cache is kept (default: a temporary folder)")
    add_output_arguments(parser, "hqp_kernels.json", "--json")
    parser.add_argument("--merge", nargs="+", type=Path, help="merge the JSON of consecutive runs into --json")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.merge:
        code = merge(args.merge, args.out)
        if args.save:
            write_json(json.loads(args.out.read_text()), args.out, save=bool(args.save), indent=1)  # (its own name: the warm runs too)
        return code
    if args.worker:
        Path(args.worker).write_text(json.dumps(sweep(args.first, args.count, args.reuse)))
        return 0
    names = [name.strip() for name in args.kernels.split(",")]
    unknown = [name for name in names if name not in KERNELS]
    if unknown:
        parser.error(f"unknown kernel(s) {unknown}; choose among {list(KERNELS)}")
    outcomes, seconds = {}, {}
    with tempfile.TemporaryDirectory() as work:
        cache = args.cache or Path(work)
        print(f"{', '.join(names)}: {args.count} stacks from seed {args.first}, one process per kernel …", flush=True)
        began = time.monotonic()
        workers = {name: start_kernel(name, args.first, args.count, cache, Path(work) / f"{name}.json", args.reuse)
                   for name in names}
        for name, worker in workers.items():
            if worker.wait() != 0:
                raise SystemExit(f"the sweep under kernel {name} exited with {worker.returncode}")
            outcomes[name], seconds[name] = json.loads((Path(work) / f"{name}.json").read_text()), time.monotonic() - began
    failed = {name: [r for r in records if not r["ok"]] for name, records in outcomes.items()}
    paths = [{name: outcomes[name][i]["path"] for name in names} for i in range(args.count)]
    differ = [i for i, by_kernel in enumerate(paths) if len(set(by_kernel.values())) > 1]
    differ_failed = [i for i in differ if any(not outcomes[name][i]["ok"] for name in names)]
    summary = {
        "first_seed": args.first, "stacks": args.count, "reuse": args.reuse, "kernels": {name: KERNELS[name] for name in names},
        "failed": {name: len(records) for name, records in failed.items()},
        "failures": {name: records[:20] for name, records in failed.items()},
        "paths_differ": len(differ), "paths_differ_and_contract_missed": len(differ_failed),
        "paths_differ_seeds": [args.first + i for i in differ[:50]],
        "seconds": {name: round(s, 1) for name, s in seconds.items()},
    }
    print(f"{'kernel':<9} {'stacks':>7} {'contract missed':>16} {'seconds':>8}")
    for name in names:
        print(f"{name:<9} {args.count:>7} {summary['failed'][name]:>16} {summary['seconds'][name]:>8}")
    print(f"answering path differs between kernels on {len(differ)} stacks; "
          f"{len(differ_failed)} of them miss the contract under some kernel")
    write_json(summary, args.out, bool(args.save), indent=1)  # (bench/reference/<its name>: hqp_kernels_warm.json too)
    return 1 if any(failed.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
