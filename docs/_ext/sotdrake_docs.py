"""Sphinx extension of the sotdrake docs: the benchmark tables, generated from bench JSON.

At ``builder-inited`` it reads ``bench/reference.json`` (``bench/run.py --save``) and
``bench/reference/*.json`` (the other bench scripts' ``--save``: committed copies; their default
output, ``bench/reference/``, is ignored by git and never read here) and writes
``docs/_generated/benchmarks_tables.md``, which ``docs/benchmarks.md`` includes. No number on the
benchmarks page is typed by hand: rerun a bench, rebuild the docs.
"""

from __future__ import annotations

import inspect
import json
import re
import types
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "bench"


def _num(value: Any) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return f"{value:,}".replace(",", " ")
    if isinstance(value, float):
        if value == 0:
            return "0"
        if abs(value) >= 1e4 or abs(value) < 1e-2:
            return f"{value:.2e}"
        return f"{value:.3g}"
    if isinstance(value, list):
        return ", ".join(_num(v) for v in value) if len(value) <= 6 else f"{len(value)} items"
    return str(value).replace("|", "\\|")


def _table(header: list[str], rows: list[list[Any]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(_num(c) if not isinstance(c, str) else c.replace("|", "\\|") for c in row) + " |" for row in rows]
    return lines + [""]


def _flat(d: dict, prefix: str = "") -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = []
    for key, value in d.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out += _flat(value, name + ".")
        else:
            out.append((name, value))
    return out


def dynamics_tables(d: dict) -> list[str]:
    lines = [
        "### The dynamic SoT against placo (`bench/reference/dynamics.json`)",
        "",
        'Regenerate with `.venv/bin/pip install ".[bench]" && .venv/bin/python bench/dynamics.py`.',
        "",
    ]
    keys = [
        "tick_cpu_us_median",
        "tick_cpu_us_p95",
        "tick_us_median",
        "tick_us_p95",
        "floor_tick_cpu_us_median",
        "ratio_to_floor_cpu_median",
        "com_rms_error_m",
        "foot_rms_error_m",
        "max_torque_ratio",
        "max_friction_ratio",
        "fell",
    ]
    for scenario, run in d.items():
        if not isinstance(run, dict) or "sotdrake" not in run:
            continue
        peers = [p for p in ("sotdrake", "placo") if isinstance(run.get(p), dict)]
        header = ["measure", *[f"{p} {run[p].get('version', '')}".strip() for p in peers]]
        rows = [[k, *[run[p].get(k) for p in peers]] for k in keys if any(k in run[p] for p in peers)]
        lines += [f"`{scenario}`, {_num(run.get('duration_s'))} s of simulated time:", ""]
        lines += _table(header, rows)
    return lines


def hostile_tables(d: dict) -> list[str]:
    lines = [
        "### Hostile inputs and randomized runs (`bench/reference/hostile.json`)",
        "",
        "Regenerate with `.venv/bin/python bench/hostile.py`.",
        "",
        f"Bad inputs tried: {_num(d.get('bad_inputs'))}; answered by a `SotError`: "
        f"{_num(d.get('bad_input_status', {}).get('sot_error'))}; state changed by one: {_num(d.get('bad_input_state_changed'))}.",
        "",
    ]
    keys = [
        "runs",
        "process_exits",
        "hangs",
        "nan",
        "frozen_ticks",
        "max_contact_drift_m",
        "contacts_beyond_tolerance",
        "runs_with_limit_violation",
        "max_limit_violation",
        "runs_scaled",
        "min_velocity_scale",
        "max_worker_rss_mb",
    ]
    runs = d.get("runs", {})
    lines += _table(["measure", *runs], [[k, *[runs[s].get(k) for s in runs]] for k in keys])
    return lines


def hqp_runs_table(d: dict) -> list[str]:
    lines = [
        "### `SolverKine` on randomized TALOS runs (`bench/reference/hqp_robot_runs.json`)",
        "",
        "Regenerate with `.venv/bin/python bench/hqp_robot_runs.py`.",
        "",
    ]
    rows = [[k, v] for k, v in _flat(d) if not isinstance(v, list)]
    return lines + _table(["measure", "value"], rows)


def sweep_table(d: dict) -> list[str]:
    lines = [
        "### Sweeps: local against Ray (`bench/reference/sweep.json`)",
        "",
        'Regenerate with `.venv/bin/pip install ".[sweep]" && .venv/bin/python bench/sweep_speedup.py --targets 1000 '
        "--out out/sweep_bench`.",
        "",
    ]
    runs = d.get("runs", {})
    rows = [
        [
            engine,
            r.get("workers"),
            r.get("wall_s"),
            (d.get("targets") or 0) / r["wall_s"] if r.get("wall_s") else None,
            r.get("errors"),
        ]
        for engine, r in runs.items()
    ]
    lines += _table(["engine", "workers", "wall time (s)", "cases/s", "errors"], rows)
    lines += [
        f"{_num(d.get('targets'))} targets; speed-up of Ray over local: {_num(d.get('speedup_ray_over_local'))}; "
        f"identical tables: {_num(d.get('identical_tables'))}; {_num(d.get('cores'))} cores. What the map "
        "finds (the targets reached, the collision-free paths) is in the sweeps tutorial, measured with "
        "today's reach map.",
        "",
    ]
    return lines


def hqp_kernels_table(d: dict, name: str = "hqp_kernels.json") -> list[str]:
    warm = bool(d.get("reuse"))
    lines = [
        f"### The hierarchical QP's random stacks under three CPU kernels{', solvers reused (warm)' if warm else ''} "
        f"(`bench/reference/{name}`)",
        "",
        f"Seeds {_num(d.get('first_seed'))} to {_num((d.get('first_seed') or 0) + (d.get('stacks') or 0) - 1)} of "
        "`tests/hqp_stacks.py`, each kernel in its own process; the contract checked on every stack (no failure, "
        "bounds exact, every level as strict as the truncated stacks). "
        + ("One solver per size is reused from stack to stack, so that each solve starts from another stack's "
           "working sets. " if warm else "Each stack is solved by a new solver. ")
        + f"Regenerate with `.venv/bin/python bench/hqp_kernels.py --count 40000{' --reuse' if warm else ''}`.",
        "",
    ]
    kernels = d.get("kernels", {})
    rows = [
        [name, " ".join(f"{k}={v}" for k, v in env.items()) or "this machine's own", d.get("stacks"),
         d.get("failed", {}).get(name), d.get("seconds", {}).get(name)]
        for name, env in kernels.items()
    ]
    lines += _table(["kernel", "environment", "stacks", "contract missed", "wall time (s)"], rows)
    lines += [
        f"The answering path (each level's solver and the fallbacks taken) differs between kernels on "
        f"{_num(d.get('paths_differ'))} stacks; {_num(d.get('paths_differ_and_contract_missed'))} of them miss the "
        "contract under some kernel.",
        "",
    ]
    return lines


def generic_table(name: str, d: dict) -> list[str]:
    rows = [[k, v] for k, v in _flat(d) if not isinstance(v, list | dict)]
    return [f"### `bench/reference/{name}`", "", *_table(["key", "value"], rows)]


def reference_tables(d: dict) -> list[str]:
    """The reference run, rendered by bench/run.py's own renderer when it imports, else its key figures."""
    lines = [
        "### The kinematic tick against pink and placo (`bench/reference.json`)",
        "",
        'Regenerate with `.venv/bin/pip install ".[bench]" && .venv/bin/python bench/run.py` '
        "(`--table bench/reference.json` prints these tables from the committed run).",
        "",
    ]
    try:
        import sys

        sys.path.insert(0, str(BENCH))
        import run as bench_run  # type: ignore[import-not-found]

        return [*lines, bench_run.markdown(d), ""]
    except Exception:  # the renderer needs the package installed: fall back to the key figures
        keys = [
            "tick_us_median",
            "hqp_tick_us_median",
            "hqp_active_tick_us_median",
            "pink_tick_us_median",
            "placo_tick_us_median",
            "ratio_vs_pink",
            "realtime_factor_kinematic",
            "realtime_factor_physics",
            "marginal_task_us",
            "hqp_random_solve_ms_median",
        ]
        return [*lines, *_table(["measure", "value"], [[k, d.get(k)] for k in keys if k in d])]


def push_map_table(d: dict, name: str) -> list[str]:
    controller = d.get("controller", "kinematic")
    lines = [
        f"### Torso pushes on TALOS standing, {controller} controller (`bench/reference/{name}`)",
        "",
        f"Regenerate with `.venv/bin/python diagrams/push_map.py --controller {controller} --magnitudes 100,200,300 "
        "--directions 2 --push-durations 0.1,0.2 --out out/push` and copy its `summary.json`. A fall is the shared "
        f"criterion: tilt > {_num(d.get('fall_tilt_deg'))}°, base drop > {_num(d.get('fall_base_drop_m'))} m, "
        f"a held sole slid > {_num(d.get('fall_slip_m'))} m, another body on the ground.",
        "",
    ]
    keys = ["magnitude_n", "direction_deg", "push_duration_s", "impulse_ns", "fell", "fall_reason", "max_base_tilt_deg",
            "max_sole_slip_m", "base_drift_m"]
    return lines + _table(keys, [[row.get(k) for k in keys] for row in d.get("case_results", [])])


def _fixed(value: Any, digits: int = 1) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def entity_profile_table(d: dict) -> list[str]:
    lines = [
        "### Where the tick's time goes, per entity (`bench/reference/entity_profile.json`)",
        "",
        f"CPU time per tick of each entity kind, every callback timed (exclusive time: what a callback's "
        f"input ports trigger is charged to the entities upstream), the timer's own cost "
        f"({_num(d.get('timer_cost_us_per_call'))} µs per call) subtracted; beside it, the same kind in "
        f"`bench/floor.py`'s graph (callbacks without maths) timed in the same run. {_num(d.get('tasks'))} tasks "
        f"(`FeatureGeneric` is the CoM's feature). Regenerate with `.venv/bin/python bench/profile_entities.py --save`.",
        "",
    ]
    stacks = d.get("stacks", {})
    floor_tick = next((r.get("tick_cpu_us_median") for key, r in stacks.items() if key.startswith("floor")), None)
    for key, r in stacks.items():
        if key.startswith("floor"):
            continue
        lines += [f"**{key}**: median tick {_fixed(r.get('tick_cpu_us_median'), 0)} µs CPU (the floor's graph: "
                  f"{_fixed(floor_tick, 0)} µs).", ""]
        rows = [[kind, k.get("instances"), _fixed(k.get("calls_per_tick")), _fixed(k.get("us_per_tick")),
                 _fixed(k.get("us_per_entity_net")), _fixed(k.get("floor_us_per_entity")), _fixed(k.get("ratio_to_floor"))]
                for kind, k in r.get("kinds", {}).items()]
        lines += _table(["entity kind", "instances", "calls per tick", "µs per tick", "µs per entity", "floor µs per entity",
                         "ratio to floor"], rows)
    return lines


def marginal_table(d: dict) -> list[str]:
    lines = [
        "### The marginal cost of a task, by kind (`bench/reference/marginal.json`)",
        "",
        f"The base stack (both soles, the right hand) and the same stack with one more task of each kind at the "
        f"bottom, timed in the same turns as `bench/floor.py`'s graph: the median tick's CPU time, the difference "
        f"(the kind's marginal cost) and its ratio to the floor's slope ({_fixed(d.get('floor_slope_cpu_us'))} µs per "
        f"task; target ≤ 2). Medians over {_num(d.get('repeat'))} repeats of {_num(d.get('ticks'))} ticks. "
        f"Regenerate with `.venv/bin/python bench/marginal.py --save`.",
        "",
    ]
    rows = []
    for solver, r in d.get("solvers", {}).items():
        for kind, k in r.get("kinds", {}).items():
            rows.append([f"`{solver}`", kind, _fixed(r.get("base_tick_cpu_us"), 0), _fixed(k.get("tick_cpu_us"), 0),
                         _fixed(k.get("marginal_cpu_us")), _fixed(k.get("ratio_to_floor_slope"), 2)])
    return lines + _table(["solver", "kind added", "base µs", "with it µs", "marginal µs", "ratio to the floor's slope"], rows)


RENDERERS = {
    "entity_profile.json": entity_profile_table,
    "marginal.json": marginal_table,
    "push_map_kinematic.json": lambda d: push_map_table(d, "push_map_kinematic.json"),
    "push_map_dynamic.json": lambda d: push_map_table(d, "push_map_dynamic.json"),
    "dynamics.json": dynamics_tables,
    "hostile.json": hostile_tables,
    "hqp_kernels.json": hqp_kernels_table,
    "hqp_kernels_warm.json": lambda d: hqp_kernels_table(d, "hqp_kernels_warm.json"),
    "hqp_robot_runs.json": hqp_runs_table,
    "sweep.json": sweep_table,
}


def benchmark_markdown() -> str:
    lines: list[str] = ["<!-- generated by docs/_ext/sotdrake_docs.py from bench JSON: do not edit -->", ""]
    if (BENCH / "reference.json").exists():
        lines += reference_tables(json.loads((BENCH / "reference.json").read_text()))
    for path in sorted((BENCH / "reference").glob("*.json")):
        data = json.loads(path.read_text())
        render = RENDERERS.get(path.name)
        lines += render(data) if render else generic_table(path.name, data)
    return "\n".join(lines) + "\n"


def _is_data(obj: Any) -> bool:
    """A constant or a type alias (``Case = dict[str, object]``), not a class, function or module."""
    if isinstance(obj, types.GenericAlias | types.UnionType) or type(obj).__module__ == "typing":
        return True
    return not (inspect.isclass(obj) or inspect.isroutine(obj) or inspect.ismodule(obj) or callable(obj))


def _annotation(value: Any) -> str:
    text = repr(value)
    if len(text) <= 70 and " at 0x" not in text and "\n" not in text:
        return f"= {text}"
    size = f", {len(value)} entries" if hasattr(value, "__len__") else ""
    return f": {type(value).__name__}{size}"


#: The modules whose API page lists its constants (docs/api/<name>.md includes _generated/api_data_<name>.md).
API_MODULES = (
    "sotdrake",
    "sotdrake.features",
    "sotdrake.solvers",
    "sotdrake.hqp",
    "sotdrake.dynamics",
    "sotdrake.walking",
    "sotdrake.robots",
    "sotdrake.physics",
    "sotdrake.collision",
    "sotdrake.live",
    "sotdrake.sweep",
)


def _comment_docs() -> dict[str, list[str]]:
    """``#:`` comments of the package's module-level constants, by name, read from every module's
    source (nothing imported)."""
    from sphinx.pycode import ModuleAnalyzer

    package = ROOT / "sotdrake"
    docs: dict[str, list[str]] = {}
    for path in sorted(package.rglob("*.py")):
        name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        try:
            found = ModuleAnalyzer.for_string(path.read_text(), name, str(path)).find_attr_docs()
        except Exception:  # a module that does not parse: nothing to read
            continue
        for (scope, attribute), lines in found.items():
            if scope == "" and attribute not in docs:
                docs[attribute] = list(lines)
    return docs


def api_data_markdown(module_name: str, comments: dict[str, list[str]]) -> str:
    """``autodata`` for the constants of a module's ``__all__``: autodoc leaves out an imported constant.
    A subpackage leaves out those of ``sotdrake.__all__`` (documented on the top-level page)."""
    import importlib

    import sotdrake

    module = importlib.import_module(module_name)
    top = [getattr(sotdrake, n) for n in sotdrake.__all__] if module_name != "sotdrake" else []
    names = [n for n in module.__all__ if _is_data(getattr(module, n)) and not any(getattr(module, n) is o for o in top)]
    if not names:
        return "<!-- no constants in this module's __all__ -->\n"
    blocks = []
    for n in names:
        text = f".. autodata:: {module_name}.{n}\n   :annotation: {_annotation(getattr(module, n))}\n"
        if comments.get(n):
            text += "\n" + "".join(f"   {line}\n" for line in comments[n])
        blocks.append(text)
    return "## Constants and type aliases\n\n```{eval-rst}\n" + "\n".join(blocks) + "```\n"


def api_summary_markdown(module_name: str) -> str:
    """An ``autosummary`` table of a module's ``__all__`` (its own names, as its page documents them):
    the names at a glance, each with the first line of its docstring, linking to its entry below."""
    import importlib

    import sotdrake

    module = importlib.import_module(module_name)
    top = [getattr(sotdrake, n) for n in sotdrake.__all__] if module_name != "sotdrake" else []
    names = [n for n in module.__all__ if not any(getattr(module, n) is o for o in top)]
    if not names:
        return "<!-- every name of this module is documented on the top-level page -->\n"
    body = "".join(f"   ~{module_name}.{n}\n" for n in names)
    return "```{eval-rst}\n.. autosummary::\n\n" + body + "```\n"


def _write(path: Path, text: str) -> None:
    if not path.exists() or path.read_text() != text:  # unchanged: no rebuild of the page
        path.write_text(text)


def write_generated(app) -> None:
    out = Path(app.srcdir) / "_generated"
    out.mkdir(exist_ok=True)
    _write(out / "benchmarks_tables.md", benchmark_markdown())
    comments = _comment_docs()
    for module_name in API_MODULES:
        _write(out / f"api_data_{module_name.split('.')[-1]}.md", api_data_markdown(module_name, comments))
        _write(out / f"api_summary_{module_name.split('.')[-1]}.md", api_summary_markdown(module_name))


_LITERAL = re.compile(r"``.+?``", re.S)


def close_literals(text: str) -> str:
    """An inline literal directly followed by a letter (the plural of a literal class name) is not
    closed for docutils: put an escaped space (which renders as nothing) between them. Literals are paired from the
    left, over the whole docstring (one may span lines)."""
    out, position = [], 0
    for match in _LITERAL.finditer(text):
        out.append(text[position : match.end()])
        if match.end() < len(text) and text[match.end()].isalpha():
            out.append("\\ ")
        position = match.end()
    out.append(text[position:])
    return "".join(out)


def fix_docstring(app, what, name, obj, options, lines) -> None:
    """Make plain-text docstrings valid reST, without changing what they say."""
    inherited = {(inspect.getdoc(t) or "").strip() for t in (type(obj), getattr(obj, "__origin__", None)) if t is not None}
    if what == "data" and lines and "\n".join(lines).strip() in inherited:
        lines[:] = []  # a constant without a docstring of its own: not its type's (dict's, str's) docstring
        return
    text = "\n".join(lines)
    if "``" in text:
        mended = close_literals(text)
        if mended != text:
            lines[:] = mended.split("\n")


def skip_top_level_names(app, what, name, obj, skip, options):
    """Which members an API page lists. The top-level page documents every name of ``sotdrake.__all__``;
    a subpackage's page leaves out the names it shares with it: they are documented once (else Sphinx
    sees two descriptions of one canonical object). Constants are documented by the generated
    ``autodata`` blocks (api_data_<module>.md), never by automodule."""
    import sotdrake

    if what != "module":
        return skip
    if _is_data(obj):
        return True
    if app.env.docname == "api/sotdrake":
        return False if name in sotdrake.__all__ else skip
    top_level = any(obj is getattr(sotdrake, n, None) for n in sotdrake.__all__)
    return True if top_level else skip


def setup(app):
    app.connect("builder-inited", write_generated)
    app.connect("autodoc-process-docstring", fix_docstring)
    app.connect("autodoc-skip-member", skip_top_level_names)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
