"""The README's "Your first stack" script runs as written and does what the README says."""

import re
from pathlib import Path

import numpy as np

README = Path(__file__).resolve().parents[1] / "README.md"


def first_stack_code() -> str:
    section = README.read_text().split("## Your first stack", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert len(blocks) == 1, "the section holds one complete script"
    return blocks[0]


def test_first_stack_runs_as_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__main__"}
    exec(compile(first_stack_code(), "README.md: Your first stack", "exec"), namespace)
    context = namespace["simulator"].get_context()
    hand, waist, target = namespace["hand"], namespace["waist"], np.asarray(namespace["target"])
    assert np.linalg.norm(hand.current_pose(context).translation() - target) < 1e-4
    np.testing.assert_allclose(
        waist.current_pose(context).GetAsMatrix4(), waist.current_pose().GetAsMatrix4(), atol=1e-9
    )  # priority 1 held
    assert "hand to target (m):" in capsys.readouterr().out
    recording = (tmp_path / "recording.html").read_text()
    assert "<html" in recording.lower() and len(recording) > 1e5


def test_the_scripts_use_the_public_api():
    import sotdrake

    for name in sotdrake.__all__:
        assert hasattr(sotdrake, name), name
    public = set(sotdrake.__all__)
    # The wings sotdrake imports on first use (dynamics, physics, walking …) are packages with their
    # own public names: a script may import those from the wing.
    wings = tuple(module.lstrip(".") for module in sotdrake._LAZY)
    for script in [*(README.parent / "diagrams").glob("*.py"), *(README.parent / "sotdrake" / "scenarios").glob("[!_]*.py")]:
        text = script.read_text()
        assert re.search(r"^from sotdrake import", text, re.M), script.name
        for module, names in re.findall(r"from sotdrake\.([\w.]+) import \(?([\w, \n]+)\)?", text):
            if module.startswith(wings):
                continue
            sideways = public & {n.strip() for n in names.split(",")}
            assert not sideways, f"{script.name} imports {sideways} from a submodule, not from sotdrake"
