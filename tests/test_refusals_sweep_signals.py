"""Refusals at the moment of the mistake, with nothing changed or written: sweeps and their tables,
introspection, the control graph, the manipulability's gradient and selection masks; and a signal
read from a context keeps the value it had when it was read."""

import io

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, Integrator

from sotdrake import visualization
from sotdrake.exceptions import InvalidInput
from sotdrake.introspection import displayAll, displaySignals, signal, signals_report
from sotdrake.manipulability import manipulability_and_gradient
from sotdrake.selection import parse_selection
from sotdrake.sweep import grid, run_sweep


class _MovingPose(LeafSystem):
    """An abstract output: the pose ``(t, 0, 0)`` at the context's time."""

    def __init__(self):
        super().__init__()
        self.DeclareAbstractOutputPort("pose", lambda: AbstractValue.Make(RigidTransform()),
                                       lambda context, out: out.set_value(RigidTransform([context.get_time(), 0.0, 0.0])))


def _moving_diagram():
    builder = DiagramBuilder()
    source = builder.AddNamedSystem("speed", ConstantVectorSource([1.0, 2.0]))
    integrator = builder.AddNamedSystem("integrator", Integrator(2))
    pose = builder.AddNamedSystem("pose", _MovingPose())
    builder.Connect(source.get_output_port(), integrator.get_input_port())
    return builder.Build(), integrator, pose, builder


@pytest.fixture
def moving():
    return _moving_diagram()


# --- introspection --------------------------------------------------------------------------
def test_a_signal_keeps_the_value_it_had_when_it_was_read(moving):
    diagram, integrator, pose, _ = moving
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    integrator.set_integral_value(integrator.GetMyMutableContextFromRoot(context), [0.5, 0.5])
    simulator.Initialize()
    y, X = signal(integrator, "y0", context), signal(pose, "pose", context)
    y_then, p_then = np.array(y, copy=True), X.translation().copy()
    simulator.AdvanceTo(0.5)
    y_now, X_now = signal(integrator, "y0", context), signal(pose, "pose", context)
    np.testing.assert_allclose(y_now, [1.0, 1.5])  # the simulation moved on …
    assert X_now.translation()[0] == pytest.approx(0.5)
    np.testing.assert_array_equal(y, y_then)  # … the values read before did not
    np.testing.assert_array_equal(X.translation(), p_then)


def test_the_signal_reports_refuse_what_is_not_a_system_or_a_diagram(moving):
    diagram, integrator, _, builder = moving
    context = diagram.CreateDefaultContext()
    printed = io.StringIO()
    with pytest.raises(InvalidInput, match="signals_report: system"):
        signals_report("integrator", context)  # type: ignore[arg-type]
    with pytest.raises(InvalidInput, match="displaySignals: system"):
        displaySignals("integrator", context, file=printed)  # type: ignore[arg-type]
    for wrong in ("diagram", builder, integrator):
        with pytest.raises(InvalidInput, match="displayAll: diagram"):
            displayAll(wrong, context, file=printed)  # type: ignore[arg-type]
    assert printed.getvalue() == ""
    displayAll(diagram, context, file=printed)
    assert "integrator" in printed.getvalue()


# --- control graph --------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["control.dot", "control.png", "control"])
def test_the_control_graph_refuses_a_path_that_is_not_an_svg(moving, tmp_path, name):
    with pytest.raises(InvalidInput, match=r"write_control_graph: path must end in \.svg"):
        visualization.write_control_graph(moving[0], tmp_path / name)
    assert list(tmp_path.iterdir()) == []


# --- sweeps ---------------------------------------------------------------------------------
def _counting():
    calls: list[dict] = []
    return calls, lambda case: calls.append(case) or {"y": 1}


@pytest.mark.parametrize("settings", [["dt", 0.01], "dt=0.01", {1: "dt"}])
def test_run_sweep_refuses_bad_settings_before_any_case_runs(settings):
    calls, function = _counting()
    with pytest.raises(InvalidInput, match="settings"):
        run_sweep(function, grid({"x": [1, 2, 3]}), settings=settings, progress=False)
    assert calls == []
    assert run_sweep(function, grid({"x": [1]}), settings={"dt": 0.01}, progress=False).settings == {"dt": 0.01}


@pytest.mark.parametrize(("options", "named"), [
    ({"num_cpus": 4}, "num_cpus"),
    ({"num_cpus": 2, "engine": "ray", "address": "auto"}, "num_cpus"),
    ({"progress": "no"}, "progress"),
    ({"progress": 0}, "progress"),
])
def test_run_sweep_refuses_an_option_it_would_ignore_or_misread(options, named):
    calls, function = _counting()
    with pytest.raises(InvalidInput, match=named):
        run_sweep(function, [{"x": 1}], **{"progress": False, **options})
    assert calls == []


@pytest.mark.parametrize("value", [object(), None, [1.0, 2.0], np.array([1.0, 2.0]), {"a": 1}])
def test_run_sweep_refuses_a_case_value_that_is_not_plain(value):
    calls, function = _counting()
    with pytest.raises(InvalidInput, match="case 1, parameter 'x'"):
        run_sweep(function, [{"x": 1.0}, {"x": value}], progress=False)
    assert calls == []


def test_run_sweep_takes_numpy_scalars_as_plain_values():
    seen = []
    result = run_sweep(lambda case: seen.append(case) or {"y": 1},
                       [{"x": np.float64(1.5), "n": np.int64(2), "b": np.bool_(True), "s": np.str_("a")}], progress=False)
    assert [type(v) for v in seen[0].values()] == [float, int, bool, str]
    assert result.rows[0] == {"case": 0, "x": 1.5, "n": 2, "b": True, "s": "a", "status": "ok", "error": "", "y": 1}


@pytest.fixture(scope="module")
def small_result():
    return run_sweep(lambda case: {"y": case["x"]}, [{"x": 1}], progress=False)


def test_a_sweep_table_is_not_written_over_a_file(small_result, tmp_path):
    existing = tmp_path / "results"
    existing.write_text("kept")
    with pytest.raises(InvalidInput, match="out"):
        small_result.write(existing)
    with pytest.raises(InvalidInput, match="out"):
        small_result.write(existing / "sub")
    assert existing.read_text() == "kept" and list(tmp_path.iterdir()) == [existing]


@pytest.mark.parametrize("name", ["", "a/b", ".hidden", "..", 5, None])
def test_a_sweep_table_name_is_a_file_name_without_a_folder(small_result, tmp_path, name):
    out = tmp_path / "new" / "out"
    with pytest.raises(InvalidInput, match="name"):
        small_result.write(out, name)
    assert list(tmp_path.iterdir()) == []


def test_a_sweep_table_is_written_in_a_new_folder(small_result, tmp_path):
    paths = small_result.write(tmp_path / "new" / "out", "table")
    assert paths["csv"] == tmp_path / "new" / "out" / "table.csv" and paths["meta"].exists()


# --- manipulability -------------------------------------------------------------------------
def _jacobian():
    J = np.random.default_rng(3).normal(size=(6, 4))
    return J, np.array([0.1, 0.2, 0.3]), np.triu(np.ones((4, 4), dtype=bool), 1)


@pytest.mark.parametrize(("change", "named"), [
    (lambda J, p, up, rows: (np.full_like(J, np.nan), p, up, rows), "J_WF"),
    (lambda J, p, up, rows: (J[:3], p, up, rows), "J_WF"),
    (lambda J, p, up, rows: (J, p[:2], up, rows), "p_WF"),
    (lambda J, p, up, rows: (J, [np.inf, 0, 0], up, rows), "p_WF"),
    (lambda J, p, up, rows: (J, p, up[:3], rows), "upstream"),
    (lambda J, p, up, rows: (J, p, up, np.array([7])), "rows"),
    (lambda J, p, up, rows: (J, p, up, np.array([-1])), "rows"),
    (lambda J, p, up, rows: (J, p, up, np.array([3, 3])), "rows"),
    (lambda J, p, up, rows: (J, p, up, np.array([3.0])), "rows"),
])
def test_the_manipulability_gradient_refuses_bad_inputs(change, named):
    J, p, upstream = _jacobian()
    with pytest.raises(InvalidInput, match=f"manipulability_and_gradient: {named}"):
        manipulability_and_gradient(*change(J, p, upstream, np.array([3, 4, 5])))
    mu, gradient = manipulability_and_gradient(J, p, upstream, np.array([3, 4, 5]))
    assert mu > 0 and gradient.shape == (4,) and np.all(np.isfinite(gradient))
    with pytest.raises(InvalidInput, match="columns"):
        manipulability_and_gradient(J, p, upstream, np.array([3, 4, 5]), np.ones(3, dtype=bool))


# --- selection masks ------------------------------------------------------------------------
@pytest.mark.parametrize(("mask", "dimension", "named"), [
    (["1"], 3, "mask"), (("1", "1"), 3, "mask"), (b"11", 3, "mask"), ("1", 3.0, "dimension"), ("1", [3], "dimension"),
])
def test_a_selection_mask_of_the_wrong_type_is_refused(mask, dimension, named):
    with pytest.raises(InvalidInput, match=named):
        parse_selection(mask, dimension)
    assert list(parse_selection("101", np.int64(3))) == [0, 2]
