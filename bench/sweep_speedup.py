#!/usr/bin/env python3
"""The reach map swept twice, ``--engine local`` then ``--engine ray``: wall times, speed-up, and
whether both tables are byte for byte the same.

    python bench/sweep_speedup.py --targets 1000 --out out/sweep_bench   # ~20-40 min on 2 cores

Writes ``--result`` (default ``bench/results/sweep.json``, ignored by git; ``--save``: also the
committed ``bench/reference/sweep.json``) (and both runs' outputs under ``--out``). The wall times are
end to end: for ``ray`` they include starting the local runtime and building one diagram per worker.
The host's load average before and after each run is recorded with it: on a shared machine the
ratio, not the absolute times, is the number to read.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from sotdrake.scenarios import reach_map

sys.path.insert(0, str(HERE))
from output import add_output_arguments, write_json


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--targets", type=int, default=1000)
    parser.add_argument("--out", type=Path, default=Path("out/sweep_bench"))
    add_output_arguments(parser, "sweep.json", flag="--result")
    parser.add_argument("--engines", default="local,ray",
                        help="engines to run now; the others are read from an earlier run's --out")
    args = parser.parse_args(argv)
    runs = {}
    for engine in ("local", "ray"):
        out = args.out / engine
        if engine in args.engines.split(","):
            summary = reach_map.main(["--targets", str(args.targets), "--engine", engine, "--out", str(out), "--quiet"])
        else:
            summary = json.loads((out / "summary.json").read_text())
        runs[engine] = {key: summary[key] for key in ("wall_s", "workers", "errors", "reached_within_1cm",
                                                      "load_average_before", "load_average_after")}
    local_csv = (args.out / "local" / "reach_map.csv").read_bytes()
    ray_csv = (args.out / "ray" / "reach_map.csv").read_bytes()
    result = {
        "targets": args.targets,
        "case": {"duration_s": summary["duration_s"], "dt_s": summary["dt_s"], "ticks": summary["ticks_per_case"]},
        "runs": runs,
        "speedup_ray_over_local": runs["local"]["wall_s"] / runs["ray"]["wall_s"],
        "identical_tables": local_csv == ray_csv,
        "cores": os.cpu_count(),
        "machine": platform.platform(),
    }
    write_json(result, args.result, args.save)
    print(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
