"""The public API: what a user composes is importable from ``sotdrake``, listed in ``__all__`` and
documented; a joint-limit task is one line."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

import sotdrake

ROOT = Path(__file__).resolve().parents[1]


def diagram_imports() -> dict[str, set[str]]:
    """Every name the scenarios (``diagrams/*.py`` and the modules they run, ``sotdrake/scenarios/``)
    import from ``sotdrake`` or one of its modules → the files. Not counted: the names of a
    scenario module and of the walking controller, reached through their modules."""
    names: dict[str, set[str]] = {}
    for script in sorted([*(ROOT / "diagrams").glob("*.py"), *(ROOT / "sotdrake" / "scenarios").glob("[!_]*.py")]):
        for node in ast.walk(ast.parse(script.read_text())):
            if (isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "sotdrake"
                    and not node.module.startswith(("sotdrake.scenarios", "sotdrake.walking.controller"))):
                for alias in node.names:
                    names.setdefault(alias.name, set()).add(script.name)
    return names


def test_every_name_the_scripts_use_is_public():
    names = diagram_imports()
    assert len(names) > 40
    missing = sorted(name for name in names if name not in sotdrake.__all__)
    assert not missing, f"used by diagrams/ but not in sotdrake.__all__: {missing}"
    for name in names:
        assert getattr(sotdrake, name) is not None


def test_all_resolves_and_is_documented():
    assert len(set(sotdrake.__all__)) == len(sotdrake.__all__)
    undocumented = []
    for name in sotdrake.__all__:
        value = getattr(sotdrake, name)
        if (inspect.isclass(value) or inspect.isfunction(value)) and not (value.__doc__ or "").strip():
            undocumented.append(name)
    assert not undocumented


@pytest.mark.parametrize(
    "name",
    [
        "Feature6d",
        "Feature6dDesired",
        "FeatureGeneric",
        "FeatureGenericDesired",
        "FeatureJointLimits",
        "FeaturePosture",
        "FeatureRelative6d",
        "FeatureVisualPoint",
        "Feature1D",
        "Task",
        "TaskPD",
        "TaskInequality",
        "TaskDynPD",
        "GainAdaptive",
        "GainHyperbolic",
        "SOT",
        "SolverKine",
        "SolverDyn",
        "Contact6d",
        "Tracer",
        "add_state_publisher",
        "add_signal_publisher",
        "MetaTaskKineJointLimits",
        "MetaTaskKinePosture",
        "RobotModel",
        "check_stack",
    ],
)
def test_composable_entities_are_public(name):
    assert name in sotdrake.__all__ and getattr(sotdrake, name) is not None


def test_dir_lists_the_lazy_names():
    assert {"SolverDyn", "PatternGenerator", "run_sweep"} <= set(dir(sotdrake))
    with pytest.raises(AttributeError, match="no attribute 'NoSuchThing'"):
        sotdrake.NoSuchThing  # noqa: B018


def test_joint_limit_task_in_one_line_brings_a_joint_back_inside_its_margin():
    from sotdrake import MetaTaskKine6d, MetaTaskKineJointLimits, add_sot, gotoNd, load_robot, robot

    model = load_robot("ur5")
    lower, upper = model.plant.GetPositionLowerLimits(), model.plant.GetPositionUpperLimits()
    q0 = model.reference_posture.copy()
    q0[0] = upper[0] - 0.05 * (upper[0] - lower[0])  # inside the limits, outside a 10 % margin
    builder = DiagramBuilder()
    bot = robot(builder, model, q0=q0)
    sot = add_sot(bot, solver="hqp")
    limits = MetaTaskKineJointLimits(bot, margin=0.1)
    assert limits.joint_names[0] == "shoulder_pan_joint"
    tool = MetaTaskKine6d("tool", bot, "tool")
    gotoNd(tool, [0.3, 0.3, 0.4], "111", 2.0)
    sot.push(limits)
    sot.push(tool)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(1.0)
    q = bot.device.GetOutputPort("state").Eval(bot.device.GetMyContextFromRoot(simulator.get_context()))
    band = 0.1 * (upper - lower)
    assert q[0] <= upper[0] - band[0] + 0.01  # back inside (the gain, 10/s, leaves e^-10 of the excess)
    assert np.all(q >= lower + band - 0.01) and np.all(q <= upper - band + 0.01)


def test_a_feature_of_your_own_becomes_a_task_in_one_line():
    from sotdrake import FeaturePosture, MetaTaskKineFeature, add_sot, robot

    builder = DiagramBuilder()
    bot = robot(builder, "ur5")
    sot = add_sot(bot)
    target = bot.device.initial_position + 0.2
    away = MetaTaskKineFeature("away", bot, FeaturePosture("featureaway", bot.model.plant, target))
    builder.Connect(bot.device.GetOutputPort("state"), away.feature.GetInputPort("state"))
    away.gain.setConstant(5.0)
    sot.push(away)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(1.0)
    q = bot.device.GetOutputPort("state").Eval(bot.device.GetMyContextFromRoot(simulator.get_context()))
    np.testing.assert_allclose(q, target, atol=0.2 * np.exp(-5.0) * 1.5)
    with pytest.raises(sotdrake.InvalidInput, match="expected a feature"):
        MetaTaskKineFeature("bad", bot, bot.dynamic)
