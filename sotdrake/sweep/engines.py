"""Running a case function over cases: ``local`` (in this process, one core) or ``ray``.

The case function takes one case (a dict of parameters) and returns its summary (a dict of
plain values: numbers, strings, lists, nested dicts). Both engines call it the same way and keep
a failing case as a row with its error (``"ExceptionType: message"``) instead of stopping; the rows
come back sorted by case index, so the same function gives the same table from either engine.

``ray`` starts a local Ray runtime for the run (one worker per core, or ``num_cpus``) and shuts it
down after, or joins an existing cluster with ``address`` (``"auto"``, ``"ray://head:10001"``, …).
Each worker deserializes the case function once and keeps it, so a module-level cache the function
fills (a built diagram, say) is built once per worker, not once per case. The code reaches the
workers this way: on a local runtime the workers get this process's ``sys.path``; on a cluster,
``sotdrake`` itself is shipped with the job (Ray's ``py_modules``) and the module of the case
function (a script in ``diagrams/``, a test) is pickled by value, as are ``by_value`` modules.

Memory: every diagram built in a process keeps about 3 MB that pydrake never frees (a plain Drake
system does the same). A Ray worker runs at most :data:`CASES_PER_WORKER` cases and is then
replaced by a fresh process, so a long sweep keeps each worker's memory bounded; the ``local``
engine runs every case in this process, so its memory grows with the number of cases (use it for
a few hundred cases at most).
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
import types
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ..exceptions import MAX_COUNT, InvalidInput, SotError, check_count, check_flag, os_reason
from ..writable import check_writable, writing
from .cases import check_case_value
from .table import check_parameter_name, make_row, write_csv, write_parquet

ENGINES = ("local", "ray")
#: Cases a Ray worker runs before it is replaced by a fresh process (its memory freed).
CASES_PER_WORKER = 100
CaseFunction = Callable[[dict], Mapping]


class EngineUnavailable(SotError, RuntimeError):
    """The engine asked for cannot run here (Ray not installed, cluster unreachable)."""


def run_case(function: CaseFunction, index: int, case: Mapping) -> dict:
    """The row of one case: ``function(case)``'s summary, or the error it raised."""
    try:
        summary = function(dict(case))
        if not isinstance(summary, Mapping):
            raise TypeError(f"the case function must return a dict (the summary), got {type(summary).__name__}")
        return make_row(index, case, summary)
    except (Exception, SystemExit) as error:  # (SystemExit: a script's helper stopping on a bad case)
        return make_row(index, case, None, f"{type(error).__name__}: {error}")


@dataclass
class SweepResult:
    """The rows (sorted by case) and how the sweep ran (engine, workers, wall time, host load)."""

    rows: list[dict]
    engine: str
    workers: int
    wall_s: float
    load_average_before: tuple[float, float, float]
    load_average_after: tuple[float, float, float]
    settings: dict = field(default_factory=dict)

    @property
    def errors(self) -> list[dict]:
        return [row for row in self.rows if row["status"] != "ok"]

    def write(self, out: str | os.PathLike, name: str = "sweep") -> dict[str, Path]:
        """``out/<name>.csv`` (always), ``out/<name>.parquet`` (with pyarrow) and
        ``out/<name>.json`` (engine, workers, wall time, load, settings; the timing lives there).
        ``out`` is a folder (made if missing) and ``name`` a file name without a folder (not empty,
        no ``/``, not starting with ``.``); anything else, or a file that cannot be written there, is
        refused with :class:`InvalidInput` naming ``out`` or ``name`` before anything is written."""
        import json

        out = _prepare_folder(out, _check_table_name(name), ("csv", "parquet", "json"))
        paths = {"csv": write_csv(self.rows, out / f"{name}.csv")}
        parquet = write_parquet(self.rows, out / f"{name}.parquet")
        if parquet is not None:
            paths["parquet"] = parquet
        meta = {
            "engine": self.engine,
            "workers": self.workers,
            "cases": len(self.rows),
            "errors": len(self.errors),
            "wall_s": self.wall_s,
            "cases_per_s": len(self.rows) / self.wall_s if self.wall_s > 0 else None,
            "load_average_before": list(self.load_average_before),
            "load_average_after": list(self.load_average_after),
            "cores": os.cpu_count(),
            "settings": self.settings,
            "tables": {k: str(v) for k, v in paths.items()},
        }
        paths["meta"] = out / f"{name}.json"
        with writing("SweepResult.write: out", paths["meta"]):
            paths["meta"].write_text(json.dumps(meta, indent=2, default=str) + "\n")
        return paths


def _check_table_name(name: object) -> str:
    """``name`` if it can name the sweep's files in their folder (``<name>.csv`` …), else InvalidInput."""
    separators = {"/", "\0", os.sep, os.altsep or "/"}
    if not isinstance(name, str) or not name or name.startswith(".") or any(c in name for c in separators):
        raise InvalidInput(f"SweepResult.write: name must be a file name without a folder (not empty, no '/', not "
                           f"starting with '.'), got {name!r:.100}")
    return name


def _prepare_folder(out: object, name: str, suffixes: Sequence[str]) -> Path:
    """The folder ``out``, made if missing, once ``out/<name>.<suffix>`` can be written for every
    suffix; else :class:`InvalidInput` naming ``out`` and the folders made here removed again."""
    if not isinstance(out, str | os.PathLike):
        raise InvalidInput(f"SweepResult.write: out must be a folder path, got {out!r:.100}")
    folder = Path(out).expanduser()
    try:
        is_file = folder.exists() and not folder.is_dir()
        missing = [f for f in (folder, *folder.parents) if not f.exists()]
    except (OSError, ValueError) as error:  # (a NUL byte, a name too long)
        raise InvalidInput(f"SweepResult.write: out: cannot write {str(folder)!r:.100}: {os_reason(error)}") from None
    if is_file:
        raise InvalidInput(f"SweepResult.write: out {str(folder)!r:.100} is a file: give a folder (made if missing)")
    try:
        with writing("SweepResult.write: out", folder):
            folder.mkdir(parents=True, exist_ok=True)
        for suffix in suffixes:
            check_writable("SweepResult.write: out", folder / f"{name}.{suffix}")
    except SotError:
        for made in missing:  # (deepest first)
            with contextlib.suppress(OSError):
                made.rmdir()
        raise
    return folder


def _progress(total: int, progress: bool, label: str):
    from tqdm import tqdm

    return tqdm(total=total, disable=not progress, file=sys.stderr, desc=label or "sweep", unit="case")


def run_local(function: CaseFunction, cases: Sequence[Mapping], progress: bool = True, label: str = "") -> list[dict]:
    """Every case in this process, in order."""
    rows = []
    with _progress(len(cases), progress, label) as bar:
        for index, case in enumerate(cases):
            rows.append(run_case(function, index, case))
            bar.update(1)
    return rows


def _import_ray():
    try:
        import ray
    except ImportError as error:
        raise EngineUnavailable(
            "engine 'ray' needs Ray, which is not installed: pip install 'sotdrake[sweep]' "
            "(or pip install 'ray>=2'); engine 'local' runs without it"
        ) from error
    return ray


def _runner(function: CaseFunction) -> Callable[[int, Mapping], dict]:
    def run(index: int, case: Mapping) -> dict:
        return run_case(function, index, case)

    return run


def _module_to_ship(function: CaseFunction) -> types.ModuleType | None:
    """The module of ``function`` (under any ``functools.partial``) when workers may not be able
    to import it: not ``__main__`` (already pickled by value), not ``sotdrake`` (shipped), not an
    installed package or the standard library."""
    import functools
    import sysconfig

    while isinstance(function, functools.partial):
        function = function.func
    module = sys.modules.get(getattr(function, "__module__", None) or "")
    if module is None or module.__name__ == "__main__" or module.__name__.split(".")[0] == "sotdrake":
        return None
    file = getattr(module, "__file__", None)
    if file is None:
        return None
    installed = {sysconfig.get_paths()[key] for key in ("stdlib", "platstdlib", "purelib", "platlib")}
    if any(Path(file).resolve().is_relative_to(Path(root).resolve()) for root in installed):
        return None
    return module


def _start_ray(ray, address: str | None, num_cpus: int | None) -> bool:
    """Connect to ``address`` or start a local runtime; True when this call started it."""
    if ray.is_initialized():
        return False
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    if address is None:
        path = os.pathsep.join([p for p in sys.path if p] + [os.environ.get("PYTHONPATH", "")]).strip(os.pathsep)
        # "local": a new runtime for this run, never a cluster found on this machine by chance.
        ray.init(address="local", num_cpus=num_cpus, include_dashboard=False, logging_level="ERROR", log_to_driver=False,
                 runtime_env={"env_vars": {"PYTHONPATH": path}})
    else:
        package = Path(__file__).resolve().parents[1]
        try:
            ray.init(address=address, logging_level="ERROR", runtime_env={"py_modules": [str(package)]})
        except (ConnectionError, RuntimeError) as error:
            raise EngineUnavailable(f"cannot join the Ray cluster at address={address!r}: {error}") from error
    return True


def run_ray(function: CaseFunction, cases: Sequence[Mapping], address: str | None = None,
            num_cpus: int | None = None, progress: bool = True, label: str = "",
            by_value: Sequence[types.ModuleType] = ()) -> tuple[list[dict], int]:
    """Every case as a Ray task (one CPU each); returns the rows sorted by case and the number of
    CPUs the runtime offered. A worker that dies (crash, out of memory) makes its case an error
    row. ``num_cpus``: None or an integer in [1, MAX_COUNT] (a numpy integer too)."""
    num_cpus = _check_num_cpus(num_cpus)
    ray = _import_ray()
    from ray import cloudpickle

    modules = list(by_value)
    module = _module_to_ship(function)
    if module is not None:
        modules.append(module)
    for m in modules:
        cloudpickle.register_pickle_by_value(m)
    started = _start_ray(ray, address, num_cpus)
    try:
        workers = int(ray.cluster_resources().get("CPU", 1))
        remote = ray.remote(num_cpus=1, max_retries=0, max_calls=CASES_PER_WORKER)(_runner(function))
        pending = {remote.remote(index, dict(case)): index for index, case in enumerate(cases)}
        rows = []
        with _progress(len(cases), progress, label) as bar:
            waiting = list(pending)
            while waiting:
                done, waiting = ray.wait(waiting, num_returns=min(len(waiting), 16), timeout=0.5)
                for ref in done:
                    try:
                        rows.append(ray.get(ref))
                    except ray.exceptions.RayError as error:
                        index = pending[ref]
                        rows.append(make_row(index, cases[index], None, f"{type(error).__name__}: {error}"))
                bar.update(len(done))
    finally:
        for m in modules:
            cloudpickle.unregister_pickle_by_value(m)
        if started:
            ray.shutdown()
    return sorted(rows, key=lambda r: r["case"]), workers


def run_sweep(function: CaseFunction, cases: Iterable[Mapping], engine: str = "local",
              address: str | None = None, num_cpus: int | None = None, progress: bool = True,
              label: str = "", settings: Mapping | None = None,
              by_value: Sequence[types.ModuleType] = ()) -> SweepResult:
    """Run ``function`` over ``cases`` with ``engine`` (``'local'`` or ``'ray'``; ``address``
    and ``num_cpus`` are Ray's). ``cases``: any iterable of dicts (a list, a generator: read once,
    before anything runs); anything else, or no case, is an :class:`InvalidInput` naming
    ``cases``; a case value is a plain float, int, str or bool (a numpy scalar is taken as one).
    ``settings``: what every case shares (durations, time step), kept in the sweep's metadata: None
    or a dict of name → value. ``num_cpus``: None or an integer in [1, MAX_COUNT] (a numpy integer
    too; above 1 with engine ``'ray'`` only). ``progress``: True or False. Every argument is
    checked before any case runs."""
    num_cpus = _check_engine(engine, address, num_cpus)
    if not callable(function):
        raise InvalidInput(f"run_sweep: the case function must be callable, got {function!r:.80}")
    progress = check_flag("run_sweep: progress", progress)
    settings = _check_settings(settings)
    cases = _materialise(cases)
    before = os.getloadavg()
    start = time.perf_counter()
    if engine == "local":
        rows, workers = run_local(function, cases, progress, label), 1
    else:
        rows, workers = run_ray(function, cases, address, num_cpus, progress, label, by_value)
    wall = time.perf_counter() - start
    return SweepResult(rows, engine, workers, wall, before, os.getloadavg(), settings)


def _check_settings(settings: object) -> dict:
    """``settings`` as a dict if it is None or a mapping with string keys, else InvalidInput."""
    if settings is None:
        return {}
    if not isinstance(settings, Mapping) or not all(isinstance(key, str) for key in settings):
        raise InvalidInput(f"run_sweep: settings must be None or a dict of name → value (what every case shares), "
                           f"got {settings!r:.100}")
    return dict(settings)


def _check_engine(engine: str, address: str | None, num_cpus: int | None) -> int | None:
    """``num_cpus`` as an int (or None); :class:`InvalidInput` for an unknown ``engine`` or a Ray
    option it cannot take (``address``, or ``num_cpus`` above 1, with engine ``'local'``, which runs
    on one core; ``num_cpus`` with ``address``: the cluster has its own CPUs)."""
    if not isinstance(engine, str) or engine not in ENGINES:
        raise InvalidInput(f"engine must be one of {ENGINES}, got {engine!r:.60}")
    if address is not None and engine != "ray":
        raise InvalidInput(f"address={address!r:.100} is for engine 'ray', not {engine!r}")
    num_cpus = _check_num_cpus(num_cpus)
    if num_cpus is not None and num_cpus > 1 and engine != "ray":
        raise InvalidInput(f"num_cpus={num_cpus} is for engine 'ray', not {engine!r} (it runs in this process, on one core)")
    if num_cpus is not None and address is not None:
        raise InvalidInput(f"num_cpus={num_cpus} is for a local Ray runtime: the cluster at address={address!r:.100} "
                           "has its own CPUs")
    return num_cpus


def _check_num_cpus(num_cpus: int | None) -> int | None:
    """``num_cpus`` as an int if it is None or an integer (Python or numpy) in [1, MAX_COUNT]."""
    return None if num_cpus is None else check_count("num_cpus", num_cpus, 1, MAX_COUNT)


def _materialise(cases: Iterable[Mapping]) -> list[dict]:
    """``cases`` as a list of dicts, read once (a generator too), each parameter name checked."""
    if isinstance(cases, (Mapping, str, bytes)) or not isinstance(cases, Iterable):
        raise InvalidInput(f"run_sweep: cases must be a list (or any iterable) of dicts of parameter name → value "
                           f"(grid(), random_cases()), got {type(cases).__name__}")
    cases = list(cases)
    if not cases:
        raise InvalidInput("run_sweep: cases is empty: a sweep needs at least one case")
    if not all(isinstance(case, Mapping) for case in cases):
        raise InvalidInput("run_sweep: every case is a dict of parameter name → value (grid(), random_cases())")
    checked = []
    for index, case in enumerate(cases):
        for name in case:
            check_parameter_name(name, "run_sweep")
        checked.append({name: check_case_value(f"run_sweep: case {index}, parameter {name!r}", value)
                        for name, value in case.items()})
    return checked
