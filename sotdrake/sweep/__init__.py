"""Sweeps: one case function (build a diagram, simulate, return the summary) run over a grid or a
random sample of parameters, in this process or on Ray, gathered into one table.

    from sotdrake.sweep import grid, run_sweep
    result = run_sweep(case_function, grid({"x": [0.1, 0.2], "z": [0.8, 1.0]}), engine="ray")
    result.write("out/sweep")   # sweep.csv, sweep.parquet (with pyarrow), sweep.json
"""

from .arguments import add_sweep_arguments, engine_options
from .cases import Case, grid, random_cases
from .engines import ENGINES, EngineUnavailable, SweepResult, run_case, run_local, run_ray, run_sweep
from .per_process import per_process
from .table import flatten, make_row, read_csv, write_csv, write_parquet

__all__ = [
    "ENGINES",
    "Case",
    "EngineUnavailable",
    "SweepResult",
    "add_sweep_arguments",
    "engine_options",
    "flatten",
    "grid",
    "make_row",
    "per_process",
    "random_cases",
    "read_csv",
    "run_case",
    "run_local",
    "run_ray",
    "run_sweep",
    "write_csv",
    "write_parquet",
]
