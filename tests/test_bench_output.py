"""The bench scripts write only where they are told: ``--out`` (default: the ignored
``bench/results/``), and the committed ``bench/reference/`` only with ``--save``."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "bench"
sys.path.insert(0, str(BENCH))

import output  # noqa: E402

#: Scripts with their own owners' output conventions (they write under bench/results/ too).
OTHERS = {"collisions_placo.py"}  # (placo's side: JSON to stdout)


def scripts() -> list[Path]:
    """The bench files that run as scripts (a ``__main__`` block), but not the others' ones."""
    return [path for path in sorted(BENCH.glob("*.py"))
            if "__main__" in path.read_text() and path.name not in OTHERS]


def git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout


def test_nothing_under_bench_results_is_tracked_and_the_defaults_are_ignored():
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    assert git("ls-files", "bench/results") == ""
    assert git("check-ignore", str(output.RESULTS / "any.json")).strip()
    assert git("ls-files", "bench/reference").strip(), "the committed runs the docs show"


@pytest.mark.parametrize("script", scripts(), ids=lambda p: p.name)
def test_each_script_has_out_and_writes_no_fixed_path(script):
    """Every script takes ``--out`` (``sweep_speedup``: ``--result`` for its JSON) and writes no file
    under a fixed path of ``bench/``: its writes go through ``--out``/``write_json``."""
    text = script.read_text()
    assert '"--out"' in text or "add_output_arguments(" in text, script.name
    tree = ast.parse(text)
    defaults = {id(k.value) for n in ast.walk(tree) if isinstance(n, ast.Call) for k in n.keywords if k.arg == "default"}
    for node in ast.walk(tree):
        if id(node) in defaults:  # an argument's default under bench/results/: the ignored folder, checked above
            assert "reference" not in ast.unparse(node), script.name
            continue
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div) and not any(
                id(child) in defaults for child in ast.walk(node)):  # HERE / "results" / …
            parts = [n.value for n in ast.walk(node) if isinstance(n, ast.Constant) and isinstance(n.value, str)]
            assert "results" not in parts and "reference" not in parts, (script.name, parts)


def test_write_json_touches_the_reference_only_with_save(tmp_path, monkeypatch):
    monkeypatch.setattr(output, "REFERENCE", tmp_path / "reference")
    out = tmp_path / "results" / "x.json"
    assert output.write_json({"a": 1}, out) == [out]
    assert json.loads(out.read_text()) == {"a": 1} and not (tmp_path / "reference").exists()
    written = output.write_json({"a": 2}, out, save=True)
    assert written == [out, tmp_path / "reference" / "x.json"]
    assert json.loads((tmp_path / "reference" / "x.json").read_text()) == {"a": 2}


def test_output_arguments_default_to_the_ignored_folder():
    import argparse

    parser = argparse.ArgumentParser()
    output.add_output_arguments(parser, "x.json", "--json")
    args = parser.parse_args([])
    assert args.out == output.RESULTS / "x.json" and args.save is None
    saved = parser.parse_args(["--json", "y.json", "--save"])
    assert saved.out == Path("y.json") and saved.save == output.REFERENCE / "x.json"  # (the bench's reference, whatever --json is)
