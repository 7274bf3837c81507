"""The benchmark's targets (:data:`TARGETS`, judged on CPU time) and its tables: the README's
markdown (:func:`markdown`, also rendered by the docs) and the terminal's (:func:`print_table`)."""

from __future__ import annotations

from host import Steal

#: The targets of the basic ``SOT`` tick: key of the verdict (CPU time: a shared machine's other
#: jobs do not inflate it by descheduling), key of the same quantity in wall-clock time, sense,
#: bound, label.
TARGETS = {
    "ratio_vs_pink": ("ratio_vs_pink_cpu_paired", "ratio_vs_pink_paired", "<=", 1.0, "basic SOT tick / pink's median (paired runs)"),
    "ratio_vs_pink_stretch": ("ratio_vs_pink_cpu_paired", "ratio_vs_pink_paired", "<=", 0.5, "the same, stretch target"),
    "tick_p99": ("tick_cpu_us_p99", "tick_us_p99", "<=", 1000.0, "basic SOT tick p99 (µs)"),
    "marginal_task": ("marginal_task_cpu_us", "marginal_task_us", "<=", 40.0, "marginal cost of one more task (µs)"),
    "realtime_factor_kinematic": ("realtime_factor_kinematic_cpu", "realtime_factor_kinematic", ">=", 3.0,
                                  "real-time factor, kinematic tutorial"),
    "realtime_factor_physics": ("realtime_factor_physics_cpu", "realtime_factor_physics", ">=", 1.0,
                                "real-time factor, physics (talos_physics reach)"),
    "hqp_random_median": ("hqp_random_solve_cpu_ms_median", "hqp_random_solve_ms_median", "<=", 1.0,
                          "HQP on random stacks, median solve (ms)"),
    "hqp_vs_plain_reference": ("hqp_random_ratio_vs_plain", "hqp_random_ratio_vs_plain", "<=", 0.5,
                               "HQP on random stacks / a plain lexicographic reference (per-stack median, CPU)"),
    "hqp_active_ratio": ("hqp_active_ratio_vs_pink", "hqp_active_ratio_vs_pink", "<=", 2.0,
                         "`SolverKine` tick with active limits / pink's median"),
}


def _values(r: dict) -> dict:
    return dict(r, tick_cpu_us_p99=r.get("tick_cpu_us", {}).get("p99"), tick_us_p99=r["tick_us"].get("p99"))


def check_targets(results: dict) -> dict:
    """``{target: True/False}`` for each target whose number (CPU time) was measured."""
    values = _values(results)
    met = {}
    for key, (cpu_key, _, sense, bound, _) in TARGETS.items():
        if values.get(cpu_key) is not None:
            met[key] = values[cpu_key] <= bound if sense == "<=" else values[cpu_key] >= bound
    return met


def _fmt(value, spec: str) -> str:
    return "n/a" if value is None else format(value, spec)


def _daqp_sentence(d: dict) -> str:
    """The README's sentence on DAQP's hierarchical mode (``bench/hierarchical_peer.py``)."""
    answers = d["answers"]
    return (f"DAQP's hierarchical mode on the same random stacks (`bench/hierarchical_peer.py`): CPU time median "
            f"{d['cpu_ms_median']:.3f} ms, the HQP's {d['ratio_median']:.1f}× that (per-stack median); its answer is "
            f"lexicographically worse than the HQP's on {answers['worse']} stacks, equal on {answers['equal']}, better on "
            f"{answers['better']} (of which {answers['better_with_looser_level_above']} by holding a level above looser), "
            f"outside the bounds on {answers['outside_bounds']}, failed on {answers['failed']}"
            + (f" (measured {d['measured']})." if "measured" in d else "."))


def markdown(r: dict) -> str:
    """The README's benchmark tables, from a run's JSON."""
    def row(name, t, acc, cpu=None):
        cpu_text = "" if cpu is None else f"{cpu['median']:.0f} / {cpu['p99']:.0f}"
        return (f"| {name} | {cpu_text} | {t['median']:.0f} | {t['p95']:.0f} | {_fmt(t.get('p99'), '.0f')} | "
                f"{acc['hand_error_m']:.1e} | {acc['max_foot_drift_m']:.1e} | {acc['max_com_drift_m']:.1e} |")

    lines = ["| peer (same scenario, same run) | CPU median / p99 (µs) | wall median (µs) | wall p95 (µs) | wall p99 (µs) "
             "| hand error (m) | max foot drift (m) | max CoM drift (m) |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |",
             row("sotdrake `SOT` (strict cascade)", r["tick_us"], r["accuracy"]["sotdrake"], r.get("tick_cpu_us")),
             row("sotdrake `SolverKine` (HQP, limits hard)", r["hqp_tick_us"], r["accuracy"]["sotdrake_hqp"]),
             row("… with joint limits active (target behind the back)", r["hqp_active_limits_tick_us"],
                 r["accuracy"]["sotdrake_hqp_active_limits"])]
    for name, label in (("pink", "pink {} (weighted QP, daqp)"), ("placo", "placo {} (C++ core; feet hard, CoM and hand soft)")):
        peer_run = r.get(name, {})
        if peer_run.get("available"):
            lines.append(row(label.format(peer_run.get("version", "")), peer_run["tick_us"], peer_run["accuracy"],
                             peer_run.get("tick_cpu_us")))
        else:
            lines.append(f"| {name} | {peer_run.get('reason', 'not run')} | | | | | | |")
    met = r.get("targets", {})
    values = _values(r)
    lines += ["", "| quantity | CPU time | wall clock | target (on CPU time) |", "| --- | --- | --- | --- |"]
    for key, (cpu_key, wall_key, sense, bound, label) in TARGETS.items():
        verdict = "" if key not in met else (" (met)" if met[key] else " (**not met**)")
        lines.append(f"| {label} | {_fmt(values.get(cpu_key), '.2f')} | {_fmt(values.get(wall_key), '.2f')} | "
                     f"{sense.replace('<=', '≤').replace('>=', '≥')} {bound:g}{verdict} |")
    for key, label in (("ratio_vs_pink_cpu", "basic SOT tick / pink's, the long runs above (CPU time)"),
                       ("ratio_vs_pink", "basic SOT tick / pink's, the long runs above (wall clock)"),
                       ("hqp_ratio_vs_pink", "`SolverKine` tick / pink's (wall clock)"),
                       ("hqp_active_ratio_vs_pink_cpu_paired", "`SolverKine` tick with active limits / pink's (paired runs, CPU time)"),
                       ("hqp_active_ratio_vs_pink_paired", "`SolverKine` tick with active limits / pink's (paired runs, wall clock)"),
                       ("ratio_vs_placo", "basic SOT tick / placo's (wall clock)")):
        if key in r:
            lines.append(f"| {label} | {r[key]:.2f} | | |")
    lines += ["", "Median tick, CPU time (µs), by number of tasks: "
              + ", ".join(f"{n}: {v:.0f}" for n, v in r.get("tick_cpu_us_median_by_tasks", {}).items())
              + "; by DoF, one hand task: "
              + ", ".join(f"{n}: {v:.0f}" for n, v in r.get("tick_cpu_us_median_by_dof", {}).items()) + ".",
              "Median tick, wall clock (µs), by number of tasks: "
              + ", ".join(f"{n}: {v:.0f}" for n, v in r["tick_us_median_by_tasks"].items())
              + "; by DoF, one hand task: " + ", ".join(f"{n}: {v:.0f}" for n, v in r["tick_us_median_by_dof"].items()) + ".",
              *([f"Framework floor (`bench/floor.py`: the same graph, callbacks without maths), CPU time: "
                 f"{r['framework_floor_cpu_us_per_task']:.1f} µs per task."] if "framework_floor_cpu_us_per_task" in r else []),
              *([_daqp_sentence(r["hqp_random"]["daqp_hierarchical"])] if "daqp_hierarchical" in r.get("hqp_random", {}) else []),
              "Breakdown of the basic tick (exclusive time): "
              + ", ".join(f"{k} {100 * v:.0f}%" for k, v in sorted(r["breakdown_fraction"].items(), key=lambda x: -x[1])) + "."]
    if "machine" in r:
        m = r["machine"]
        lines.append(f"Measured {r.get('date', '')} on {m.get('cpus')} CPUs, "
                     f"load average {', '.join(f'{x:.1f}' for x in m.get('load_average', []))}"
                     + (f", {Steal.describe(m['host_steal_fraction'])}" if "host_steal_fraction" in m else "") + ".")
    return "\n".join(lines)


def print_table(r: dict) -> None:
    def row(name, t, acc):
        return (f"{name:28s} {t['median']:9.1f} {t['p95']:9.1f} {t['p99']:9.1f} {t['max']:9.1f}   "
                f"{acc['hand_error_m']:10.2e} {acc['max_foot_drift_m']:10.2e} {acc['max_com_drift_m']:10.2e}")

    print(f"\nhand error and drifts after {r['accuracy_after_s']:.1f} s of the run; real-time factors without Meshcat")
    print(f"\n{'tick (µs), accuracy (m)':28s} {'p50':>9s} {'p95':>9s} {'p99':>9s} {'max':>9s}   "
          f"{'hand err':>10s} {'foot drift':>10s} {'CoM drift':>10s}")
    print(row("sotdrake SOT (cascade)", r["tick_us"], r["accuracy"]["sotdrake"]))
    print(row("  … its CPU time", r["tick_cpu_us"], r["accuracy"]["sotdrake"]))
    print(row("sotdrake SolverKine (HQP)", r["hqp_tick_us"], r["accuracy"]["sotdrake_hqp"]))
    print(row("  … limits active", r["hqp_active_limits_tick_us"], r["accuracy"]["sotdrake_hqp_active_limits"]))
    for name in ("pink", "placo"):
        if r[name].get("available"):
            print(row(f"{name} {r[name].get('version', '')}", r[name]["tick_us"], r[name]["accuracy"]))
        else:
            print(f"{name:28s} {r[name]['reason']}")
    print()
    for key in ("ratio_vs_pink_cpu_paired", "ratio_vs_pink_paired", "ratio_vs_pink_cpu", "ratio_vs_pink", "hqp_ratio_vs_pink",
                "hqp_active_ratio_vs_pink", "hqp_active_ratio_vs_pink_cpu_paired", "hqp_active_ratio_vs_pink_paired",
                "ratio_vs_placo", "marginal_task_cpu_us", "marginal_task_us", "realtime_factor_kinematic_cpu",
                "realtime_factor_kinematic", "realtime_factor_physics_cpu", "realtime_factor_physics"):
        if key in r:
            print(f"{key:36s} {r[key]:.2f}")
    if "gen2_collections_in_ticks" in r:
        print(f"{'full GC collections in the ticks':36s} {r['gen2_collections_in_ticks']} (target 0)")
    h = r["hqp_random"]
    print(f"\nHQP on {h['count']} random stacks (ms): median {h['median']:.3f}, p99 {h['p99']:.3f}, max {h['max']:.3f}"
          + f"; CPU time median {h['cpu_ms_median']:.3f}"
          + (f" (plain lexicographic reference {h['plain_reference_cpu_ms_median']:.3f}; per-stack ratio median "
             f"{h['ratio_median']:.2f}, target ≤ 0.5)" if "ratio_median" in h else ""))
    if "daqp_hierarchical" in h:
        d = h["daqp_hierarchical"]
        print(f"DAQP's hierarchical mode on the same stacks: CPU time median {d['cpu_ms_median']:.3f} ms (per-stack ratio "
              f"median {d['ratio_median']:.2f}); its answers against the HQP's: "
              + ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in d["answers"].items()))
    print(f"HQP solver's own share of the active-limits tick: median {r['hqp_active_solver_us_median']:.0f} µs"
          f" of {r['hqp_active_tick_us_median']:.0f} µs")
    print("\nbreakdown of the basic tick: "
          + ", ".join(f"{k} {100 * v:.0f}%" for k, v in sorted(r["breakdown_fraction"].items(), key=lambda x: -x[1])))
    print("tick (µs) by number of tasks: " + ", ".join(f"{n}: {v:.0f}" for n, v in r["tick_us_median_by_tasks"].items()))
    print(f"marginal cost of one more task: {r['marginal_task_cpu_us']:.1f} µs CPU, {r['marginal_task_us']:.1f} µs wall clock")
    if "framework_floor_cpu_us_per_task" in r:
        print("framework floor (bench/floor.py: the same graph, callbacks without maths): "
              f"{r['framework_floor_cpu_us_per_task']:.1f} µs CPU per task; "
              + ", ".join(f"{n}: {v:.0f}" for n, v in r["framework_floor_cpu_us_by_tasks"].items()))
    print("tick (µs) by DoF (one hand task): " + ", ".join(f"{n}: {v:.0f}" for n, v in r["tick_us_median_by_dof"].items()))
    print("targets (CPU time): " + ", ".join(f"{TARGETS[k][4]}: {'met' if v else 'NOT met'}" for k, v in r["targets"].items()))
