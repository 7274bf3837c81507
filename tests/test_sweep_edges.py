"""Sweeps at their edges: the API's odd inputs (a generator of cases, no cases, a 0-d axis, a summary
key that collides), and the sweep scripts' options checked before any case runs (``--out``, ``--dt``,
``--duration``, the push's end, the options of another mode), a sweep where every case fails."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from sotdrake.exceptions import InvalidInput
from sotdrake.sweep import engine_options, grid, make_row, run_sweep


@pytest.fixture(scope="module")
def reach_map():
    from sotdrake.scenarios import reach_map as module

    return module


@pytest.fixture(scope="module")
def push_map():
    from sotdrake.scenarios import push_map as module

    return module


def _one(case: dict) -> dict:
    return {"y": 2 * case["a"]}


def test_a_generator_of_cases_is_read_once_and_run():
    result = run_sweep(_one, ({"a": i} for i in range(3)), progress=False)
    assert [row["y"] for row in result.rows] == [0, 2, 4] and not result.errors


@pytest.mark.parametrize("cases", [None, 3, "abc", {"a": 1}])
def test_cases_that_are_not_a_list_of_dicts_are_named(cases):
    with pytest.raises(InvalidInput, match="cases"):
        run_sweep(_one, cases, progress=False)


def test_an_empty_generator_is_no_case():
    with pytest.raises(InvalidInput, match="at least one case"):
        run_sweep(_one, (c for c in []), progress=False)


def test_a_zero_dimensional_axis_is_named():
    with pytest.raises(InvalidInput, match="axis 'a'"):
        grid({"a": np.array(5.0)})
    with pytest.raises(InvalidInput, match="dict"):
        grid(np.array([1.0]))
    assert grid({"a": np.array([1.0, 2.0])}) == [{"a": 1.0}, {"a": 2.0}]


def test_a_summary_key_repeating_a_parameter_keeps_every_value():
    assert make_row(0, {"x": 1}, {"x": 2})["summary.x"] == 2  # (a repeated key: prefixed, as before)
    with pytest.raises(InvalidInput, match=r"summary\.x"):
        make_row(0, {"x": 1}, {"summary": {"x": 3}, "x": 2})
    row = run_sweep(lambda case: {"summary": {"x": 3}, "x": 2}, [{"x": 1}], progress=False).rows[0]
    assert row["status"] == "error" and "summary.x" in row["error"]


def test_engine_options_refuse_the_options_of_another_engine():
    def options(**given):
        return argparse.Namespace(**{"engine": "local", "address": None, "num_cpus": None, **given})

    assert engine_options(options()) == {"engine": "local", "address": None, "num_cpus": None}
    for given, named in (({"num_cpus": 7}, "--num-cpus"), ({"engine": "ray", "num_cpus": 0}, "--num-cpus"),
                         ({"engine": "ray", "address": "auto", "num_cpus": 2}, "--num-cpus"), ({"address": "auto"}, "--address")):
        with pytest.raises(SystemExit, match=named):
            engine_options(options(**given))


def test_one_target_is_the_centre_of_the_box(reach_map):
    (target,) = reach_map.targets(1)
    assert [target[axis] for axis in "xyz"] == pytest.approx([sum(reach_map.BOX[axis]) / 2 for axis in "xyz"])
    with pytest.raises(InvalidInput, match="--targets"):
        reach_map.targets(10**12, "random")


@pytest.mark.parametrize(("options", "named"), [
    (["--dt", "0.5"], "--dt"),  # λ·dt ≥ 2 for the feet's gain: every case would fail
    (["--duration", "0.01", "--dt", "0.02"], "--duration"),  # no tick
    (["--duration", "1e6"], "--duration"),
    (["--num-cpus", "7"], "--num-cpus"),
    (["--seed", "42"], "--seed"),  # (with the grid)
    (["--targets", "1000000000000", "--sampling", "random"], "--targets"),
])
def test_reach_map_refuses_before_any_case(reach_map, monkeypatch, tmp_path, options, named):
    monkeypatch.setattr(reach_map, "reach_case", lambda *a, **k: pytest.fail("a case ran"))
    with pytest.raises(SystemExit, match=named):
        reach_map.main(["--targets", "1", "--quiet", "--out", str(tmp_path / "run"), *options])
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("script", ["reach_map", "push_map"])
def test_a_sweep_checks_out_before_any_case(script, monkeypatch, tmp_path):
    from importlib import import_module

    module = import_module(f"sotdrake.scenarios.{script}")
    name = "reach_case" if script == "reach_map" else "push_case"
    monkeypatch.setattr(module, name, lambda *a, **k: pytest.fail("a case ran"))
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    with pytest.raises(SystemExit, match="--out"):
        module.main(["--quiet", "--out", str(blocker), "--duration", "1"])


@pytest.mark.parametrize(("options", "named"), [
    (["--magnitudes", "20000"], "--magnitudes"),
    (["--duration", "1e9"], "--duration"),
    (["--push-durations", "5", "--duration", "0.4", "--push-start", "0.3"], "--push-durations"),  # outlasts the run
    (["--push-start", "0.4", "--duration", "0.4"], "--push-start"),
    (["--num-cpus", "2"], "--num-cpus"),
])
def test_push_map_refuses_before_any_case(push_map, monkeypatch, tmp_path, options, named):
    monkeypatch.setattr(push_map, "push_case", lambda *a, **k: pytest.fail("a case ran"))
    with pytest.raises(SystemExit, match=named):
        push_map.main(["--magnitudes", "100", "--directions", "1", "--push-durations", "0.1", "--duration", "0.4",
                       "--push-start", "0.1", "--quiet", "--out", str(tmp_path / "run"), *options])
    assert not (tmp_path / "run").exists()


def test_the_maps_limits_are_the_packages(reach_map, push_map):
    from sotdrake import MAX_DURATION
    from sotdrake.physics import MAX_PUSH_FORCE
    from sotdrake.ranges import GAIN_DT_REFUSED
    from sotdrake.scenarios import push_momentum

    assert reach_map.GAIN_DT_REFUSED == GAIN_DT_REFUSED and push_map.MAX_PUSH_FORCE == MAX_PUSH_FORCE
    assert push_momentum.MAX_PUSH_FORCE == MAX_PUSH_FORCE and MAX_DURATION == 86400


def _failing(*args, **kwargs) -> dict:
    raise RuntimeError("this case fails")


def test_reach_map_where_every_case_fails_writes_its_summary(reach_map, monkeypatch, tmp_path):
    monkeypatch.setattr(reach_map, "reach_case", _failing)
    summary = reach_map.main(["--targets", "1", "--duration", "0.04", "--quiet", "--out", str(tmp_path)])
    assert summary["errors"] == 1 and summary["plot"] is None and summary["reached_within_1cm"] == 0
    assert json.loads((tmp_path / "summary.json").read_text())["errors"] == 1
    assert not (tmp_path / "plots.png").exists() and (tmp_path / "reach_map.csv").is_file()


def test_push_map_where_every_case_fails_writes_its_summary(push_map, monkeypatch, tmp_path):
    monkeypatch.setattr(push_map, "push_case", _failing)
    summary = push_map.main(["--magnitudes", "100", "--directions", "1", "--push-durations", "0.1", "--duration", "0.4",
                             "--push-start", "0.1", "--quiet", "--out", str(tmp_path)])
    assert summary["errors"] == 1 and summary["plot"] is None and summary["case_results"] == []
    assert json.loads((tmp_path / "summary.json").read_text())["errors"] == 1
    assert not (tmp_path / "plots.png").exists()


def test_the_sweep_scripts_help(reach_map, push_map, capsys):
    for module in (reach_map, push_map):
        with pytest.raises(SystemExit) as stopped:
            module.main(["--help"])
        assert stopped.value.code == 0
        text = " ".join(capsys.readouterr().out.split())
        assert "(default: None)" not in text and "--no-meshcat" not in text
        assert "local runtime (default: all)" in text
    assert "summary.json" in text.split("options:")[0]  # (push_map's description lists its outputs)
    with pytest.raises(SystemExit):
        reach_map.main(["--help"])
    assert "random: uniform in the box" in " ".join(capsys.readouterr().out.split())  # (--sampling's help)


def test_the_sweep_scripts_offer_no_recording(reach_map, push_map, tmp_path):
    for module in (reach_map, push_map):
        with pytest.raises(SystemExit) as stopped:
            module.main(["--no-meshcat", "--out", str(tmp_path / "run")])
        assert stopped.value.code == 2
