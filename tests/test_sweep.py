"""Sweeps: cases, the table, failures kept as rows, and the same table from both engines."""

import math
import sys
import threading

import numpy as np
import pytest

from sotdrake.exceptions import InvalidInput
from sotdrake.sweep import EngineUnavailable, grid, per_process, random_cases, read_csv, run_sweep


def damped_oscillator(case: dict) -> dict:
    """A cheap case: x'' = -ω² x - 2ζω x' from x = 1 (semi-implicit Euler, 2000 steps); fails on
    a negative damping ratio, as a case function with bad parameters would."""
    omega, zeta = case["omega"], case["zeta"]
    # Something built once per process and not picklable, as a Drake diagram is: a Ray run after a
    # local one in the same process must not try to ship it.
    with per_process("test_sweep.lock", threading.Lock):
        pass
    if zeta < 0:
        raise ValueError(f"zeta must be ≥ 0, got {zeta}")
    x, v, dt, peak = 1.0, 0.0, 1e-3, 0.0
    for _ in range(2000):
        v += dt * (-omega**2 * x - 2 * zeta * omega * v)
        x += dt * v
        peak = max(peak, abs(v))
    return {"x_final": x, "energy": {"kinetic": 0.5 * v**2, "potential": 0.5 * omega**2 * x**2},
            "peak_speed": peak, "state": np.array([x, v]), "label": f"w{omega:g}"}


def fifty_cases() -> list[dict]:
    return grid({"omega": [1.0, 2.0, 3.0, 5.0, 8.0], "zeta": [-0.1, 0.0, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 2.0]})


def test_grid_order_and_random_sample_are_deterministic():
    cases = grid({"a": [1, 2], "b": ["x", "y", "z"]})
    assert cases == [{"a": a, "b": b} for a in (1, 2) for b in "xyz"]
    assert type(grid({"a": np.arange(2)})[1]["a"]) is int  # numpy scalars become plain values
    first, again = random_cases(100, {"x": (-1, 1), "y": (2, 3)}, seed=7), random_cases(100, {"x": (-1, 1), "y": (2, 3)}, seed=7)
    assert first == again and first != random_cases(100, {"x": (-1, 1), "y": (2, 3)}, seed=8)
    xs = np.array([[c["x"], c["y"]] for c in first])
    assert xs[:, 0].min() >= -1 and xs[:, 0].max() < 1 and xs[:, 1].min() >= 2 and xs[:, 1].max() < 3
    assert xs[:, 0].std() > 0.4  # spread over the range, not a constant


@pytest.mark.parametrize("call", [
    lambda: grid({}),
    lambda: grid({"a": []}),
    lambda: random_cases(0, {"x": (0, 1)}, 1),
    lambda: random_cases(3, {"x": (1, 0)}, 1),
    lambda: run_sweep(damped_oscillator, fifty_cases(), engine="dask"),
    lambda: run_sweep(damped_oscillator, fifty_cases(), engine="local", address="auto"),
    lambda: run_sweep(damped_oscillator, []),
    lambda: run_sweep(damped_oscillator, [{"case": 1}]),
])
def test_bad_input_is_rejected(call):
    with pytest.raises(InvalidInput):
        call()


def test_local_sweep_keeps_failures_as_rows(tmp_path):
    cases = fifty_cases()
    result = run_sweep(damped_oscillator, cases, engine="local", progress=False)
    assert [row["case"] for row in result.rows] == list(range(50))
    failed = [row for row in result.rows if row["status"] == "error"]
    assert [row["zeta"] for row in failed] == [-0.1] * 5 and len(result.errors) == 5
    assert failed[0]["error"] == "ValueError: zeta must be ≥ 0, got -0.1"
    ok = {(row["omega"], row["zeta"]): row for row in result.rows if row["status"] == "ok"}
    # Undamped: the energy stays near its initial ½ω² (semi-implicit Euler keeps it to O(ω dt)).
    undamped = ok[(2.0, 0.0)]
    assert undamped["energy.kinetic"] + undamped["energy.potential"] == pytest.approx(2.0, rel=5e-3)
    # Critically damped after 2 s at ω = 8: x = (1 + ωt) e^{-ωt} ≈ 1.9e-6 (Euler within 30 %).
    assert ok[(8.0, 1.0)]["x_final"] == pytest.approx(17 * math.exp(-16), rel=0.3)
    paths = result.write(tmp_path)
    table = read_csv(paths["csv"])
    assert list(table[0])[:5] == ["case", "omega", "zeta", "status", "error"]
    assert table[0]["status"] == "error" and table[0]["x_final"] == ""
    assert float(table[1]["x_final"]) == result.rows[1]["x_final"]  # every digit written
    assert table[1]["state"].startswith("[") and table[1]["label"] == "w1"


def test_ray_is_optional(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    assert run_sweep(damped_oscillator, fifty_cases()[:3], progress=False).rows[2]["status"] == "ok"
    with pytest.raises(EngineUnavailable, match=r"pip install 'sotdrake\[sweep\]'"):
        run_sweep(damped_oscillator, fifty_cases()[:3], engine="ray", progress=False)


def test_local_and_ray_give_the_same_table(tmp_path):
    pytest.importorskip("ray")
    cases = fifty_cases()
    local = run_sweep(damped_oscillator, cases, engine="local", progress=False)
    ray = run_sweep(damped_oscillator, cases, engine="ray", num_cpus=2, progress=False)
    assert ray.engine == "ray" and ray.workers == 2
    assert len(ray.rows) == 50 and len(ray.errors) == 5
    assert ray.rows == local.rows
    local_paths, ray_paths = local.write(tmp_path / "local"), ray.write(tmp_path / "ray")
    assert local_paths["csv"].read_bytes() == ray_paths["csv"].read_bytes()
    if "parquet" in local_paths:
        import pyarrow.parquet as pq

        assert pq.read_table(local_paths["parquet"]).equals(pq.read_table(ray_paths["parquet"]))
