"""Scenarios live in the package, scripts stay thin: every ``diagrams/*.py`` is at most
:data:`MAX_LINES` lines (argument parsing, build, run, report), and no test or bench file loads a
script of ``diagrams/`` by its path: they import ``sotdrake`` (``sotdrake.scenarios.<name>``,
``sotdrake.walking.controller``). Running a script in a subprocess, as a user does, is allowed."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAX_LINES = 150
#: How a file loads a script by path: the test helper, an import spec, ``diagrams/`` on ``sys.path``.
LOADS = {
    "load_diagram": re.compile(r"""load_diagram\(\s*["'](\w+)["']"""),
    "spec_from_file_location": re.compile(r"spec_from_file_location\([^)]*diagrams"),
    "sys.path": re.compile(r"""sys\.path\.(?:insert|append)\([^\n]*["']diagrams["']"""),
}


def script_lines() -> dict[str, int]:
    return {path.stem: len(path.read_text().splitlines()) for path in sorted((ROOT / "diagrams").glob("*.py"))}


def test_every_script_is_thin():
    lines = script_lines()
    assert len(lines) >= 10
    long = {name: n for name, n in lines.items() if n > MAX_LINES}
    assert not long, f"scripts over {MAX_LINES} lines (move the scenario to sotdrake/scenarios/): {long}"


def loads_by_path(text: str) -> list[str]:
    """What ``text`` loads from ``diagrams/`` by path: the
    ``load_diagram`` calls by script name, every other way by its kind."""
    found = list(LOADS["load_diagram"].findall(text))
    for kind in ("spec_from_file_location", "sys.path"):
        found += [kind] * len(LOADS[kind].findall(text))
    return found


def test_the_check_sees_a_script_loaded_by_path():
    assert loads_by_path('appli = load_diagram("talos_appli")') == ["talos_appli"]
    assert loads_by_path('sys.path.insert(0, str(HERE.parent / "diagrams"))') == ["sys.path"]
    assert loads_by_path('spec = importlib.util.spec_from_file_location(name, ROOT / "diagrams" / "x.py")') == [
        "spec_from_file_location"]
    assert loads_by_path('subprocess.run([sys.executable, str(ROOT / "diagrams" / "walk.py")])') == []


def test_no_test_or_bench_file_loads_a_script_by_path():
    files = [path for folder in ("tests", "bench") for path in sorted((ROOT / folder).glob("*.py"))]
    assert len(files) > 50
    offenders = {path.relative_to(ROOT).as_posix(): found for path in files
                 if path.name != Path(__file__).name and (found := loads_by_path(path.read_text()))}
    assert not offenders, f"import sotdrake.scenarios.<name> instead of loading diagrams/ by path: {offenders}"


def test_a_scenario_script_says_what_it_shows_and_points_to_its_scenario():
    """The scenario module holds the description (it is ``--help``); the script's docstring stays
    short: a sentence, how to run it, and which module is the scenario."""
    import ast

    checked = 0
    for path in sorted((ROOT / "diagrams").glob("*.py")):
        text = path.read_text()
        scenario = re.search(r"from sotdrake\.scenarios\.(\w+) import", text)
        if scenario is None:  # (the tools of the folder: not scenarios)
            continue
        checked += 1
        doc = ast.get_docstring(ast.parse(text)) or ""
        assert f":mod:`sotdrake.scenarios.{scenario.group(1)}`" in doc, path.name
        assert len(doc.splitlines()) <= 12, f"{path.name}: the description belongs in sotdrake.scenarios.{scenario.group(1)}"
    assert checked >= 15


def test_every_script_ends_a_refused_option_with_one_line():
    """Each script's ``__main__`` goes through ``run_script`` (a ``SotError``: one line, exit 2, no
    traceback, no empty ``--out`` folder left)."""
    mains = {path.stem: path.read_text().split('if __name__ == "__main__":')[-1] for path in sorted((ROOT / "diagrams").glob("*.py"))}
    missing = [name for name, block in mains.items() if "run_script(" not in block and name != "ros_test"]
    assert not missing, f"scripts whose __main__ does not call run_script: {missing}"


def test_run_script_ends_a_sot_error_with_one_line_and_status_2(tmp_path, capsys, monkeypatch):
    import argparse

    import pytest

    from sotdrake import InvalidInput, run_script, start

    out = tmp_path / "new" / "run"

    def main():
        start(argparse.Namespace(duration=1.0, out=str(out), no_meshcat=True))
        raise InvalidInput("--gains: a gain must be ≥ 0")

    monkeypatch.setattr("sys.argv", ["walk.py"])
    with pytest.raises(SystemExit) as stopped:
        run_script(main)
    assert stopped.value.code == 2
    assert capsys.readouterr().err.strip() == "walk.py: error: --gains: a gain must be ≥ 0"
    assert not (tmp_path / "new").exists()  # (the folders start() made for the run, still empty)
    assert run_script(lambda: {"a": 1}) == {"a": 1} and '"a": 1' in capsys.readouterr().out


def test_a_summary_is_json_without_infinities():
    import json
    import math

    import pytest

    from sotdrake import InvalidInput
    from sotdrake.simulation import json_safe

    summary = {"min_signed_distance_m": math.inf, "runs": [{"x": float("nan"), "y": 1.5}], "n": 3}
    assert json.loads(json.dumps(json_safe(summary))) == {"min_signed_distance_m": None, "runs": [{"x": None, "y": 1.5}], "n": 3}

    cyclic: list = [1.0]
    cyclic.append(cyclic)
    deep: list = []
    for _ in range(5000):
        deep = [deep]
    for value in (cyclic, {"runs": deep}):
        with pytest.raises(InvalidInput, match="nested too deeply"):
            json_safe(value)
