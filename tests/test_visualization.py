"""The control graph's SVG without Graphviz installed (the graphviz-pure wheel's dot)."""

import shutil

from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Gain

from sotdrake import visualization


def small_diagram():
    builder = DiagramBuilder()
    source = builder.AddNamedSystem("featureDes", ConstantVectorSource([1.0, 2.0]))
    gain = builder.AddNamedSystem("gainrh", Gain(3.0, 2))
    builder.Connect(source.get_output_port(), gain.get_input_port())
    return builder.Build()


def test_the_svg_is_drawn_without_graphviz(tmp_path, monkeypatch):
    real_which = shutil.which
    monkeypatch.setattr(visualization.shutil, "which", lambda name: None if name == "dot" else real_which(name))
    command = visualization.graphviz_dot()
    assert command is not None and "graphviz-pure" in command[0] and command[1] == "-Kdot"
    written = visualization.write_control_graph(small_diagram(), tmp_path / "control_graph.svg")
    assert written == tmp_path / "control_graph.svg"
    svg = written.read_text()
    assert svg.lstrip().startswith("<?xml") and "<svg" in svg
    assert "featureDes" in svg and "gainrh" in svg and svg.count('class="edge"') == 1
    assert (tmp_path / "control_graph.dot").exists()


def test_without_any_dot_only_the_source_is_written(tmp_path, monkeypatch, caplog):
    monkeypatch.setattr(visualization, "graphviz_dot", lambda: None)
    written = visualization.write_control_graph(small_diagram(), tmp_path / "control_graph.svg")
    assert written == tmp_path / "control_graph.dot" and not (tmp_path / "control_graph.svg").exists()
    assert "graphviz-pure" in caplog.text
