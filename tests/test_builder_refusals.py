"""Building a stack: a refused meta task, contact or setting adds nothing (no entity, no op point,
no solver input, no change of the stack), and wrongly typed arguments are refused as a
:class:`SotError` naming them, not a raw ``TypeError`` from numpy or Drake."""

from __future__ import annotations

import pytest
from pydrake.systems.framework import DiagramBuilder

from sotdrake import (
    InvalidInput,
    MetaTaskKine6d,
    MetaTaskKine6dRel,
    MetaTaskKineCom,
    MetaTaskKineJointLimits,
    MetaTaskKineManipulability,
    SotError,
    StackError,
    add_sot,
    gotoNd,
    hold_feet_and_com,
    load_robot,
    robot,
)
from tests.test_own_robot import three_link


@pytest.fixture
def arm(tmp_path):
    """A three-link arm (op points ``hand``, ``link1`` …) under the basic SOT."""
    bot = robot(DiagramBuilder(), load_robot(three_link(tmp_path / "arm.urdf")))
    return bot, add_sot(bot)


def _snapshot(bot, sot) -> tuple:
    return (sorted(bot._names), sorted(s.get_name() for s in bot.builder.GetSystems()), sorted(bot.dynamic._op_points),
            list(sot.known_tasks), sot.settings().tasks, sot.settings().contacts)


@pytest.mark.parametrize("make", [
    lambda bot: MetaTaskKine6d("v", bot, "hand", "hand", inequality=True, pd=True),
    lambda bot: MetaTaskKineJointLimits(bot, gain=-1.0),
    lambda bot: MetaTaskKineJointLimits(bot, gain=1e9),
    lambda bot: MetaTaskKine6d("t", bot, "tool", "link2"),  # 't' exists: nothing of 'tool' may be declared
    lambda bot: MetaTaskKine6d(None, bot, "hand", "hand"),
    lambda bot: MetaTaskKine6d("u", bot, 5, "hand"),
    lambda bot: MetaTaskKine6d("u", bot, "hand", "palm"),
    lambda bot: MetaTaskKineCom(bot, name="t"),
    lambda bot: MetaTaskKine6dRel("r", bot, "hand", "elbow", opPointBaseRef="palm"),
    lambda bot: MetaTaskKineManipulability("m", bot, "hand", 0.01, joints="joint1"),
])
def test_a_refused_meta_task_adds_nothing(arm, make):
    bot, sot = arm
    MetaTaskKine6d("t", bot, "hand", "hand")
    before = _snapshot(bot, sot)
    with pytest.raises(SotError):
        make(bot)
    assert _snapshot(bot, sot) == before
    MetaTaskKine6d("t2", bot, "tool", "link2")  # the names and op points it would have taken are still free


def test_hold_feet_and_com_checks_both_feet_first(tmp_path):
    model = load_robot(three_link(tmp_path / "arm.urdf"), operational_points={"right-ankle": "hand"})
    bot = robot(DiagramBuilder(), model)
    sot = add_sot(bot)
    before = _snapshot(bot, sot)
    with pytest.raises(SotError, match="left-ankle"):
        hold_feet_and_com(bot, sot)
    assert _snapshot(bot, sot) == before


def test_the_basic_sot_refuses_an_inequality_contact(arm):
    bot, sot = arm
    limits = MetaTaskKineJointLimits(bot)
    for priority in ("top", "bottom"):
        with pytest.raises(StackError, match="SolverKine"):
            sot.addContact(limits, priority=priority)
    assert sot.contacts() == [] and sot.settings().tasks == []


def test_numbers_are_numbers(arm):
    bot, sot = arm
    with pytest.raises(InvalidInput, match="setVelocityLimit"):
        sot.setVelocityLimit(["2", "2", "2"])
    with pytest.raises(InvalidInput, match="setVelocityLimit"):
        sot.setVelocityLimit([True] * 3)
    limits = MetaTaskKineJointLimits(bot, inequality=True)
    with pytest.raises(InvalidInput, match="setBounds"):
        limits.task.setBounds(["-0.5"] * 3, [True] * 3)


def test_wrongly_typed_arguments(arm):
    bot, _ = arm
    hand = MetaTaskKine6d("h", bot, "hand", "hand")
    with pytest.raises(InvalidInput, match="context"):
        hand.keep(5)
    with pytest.raises(InvalidInput, match="context"):
        hand.current_pose(5)
    with pytest.raises(InvalidInput, match="add_sot takes the robot"):
        add_sot("bot")
    with pytest.raises(InvalidInput, match="name"):
        add_sot(bot, name=None)
    with pytest.raises(InvalidInput, match="DiagramBuilder"):
        robot(None, bot.model)
    with pytest.raises(InvalidInput, match="selects no component"):
        gotoNd(hand, [0.3, 0.0, 0.5], "000")


def test_visualization_helpers_check_first(arm, tmp_path):
    from pydrake.geometry import Meshcat

    from sotdrake import add_robot_visualizer, add_target_marker, save_recording

    bot, _ = arm
    meshcat = Meshcat()
    systems = [s.get_name() for s in bot.builder.GetSystems()]
    for call in (lambda: add_robot_visualizer(bot, meshcat, publish_period=-1.0), lambda: add_robot_visualizer(bot, None)):
        with pytest.raises(InvalidInput):
            call()
        assert [s.get_name() for s in bot.builder.GetSystems()] == systems
    visualizer = add_robot_visualizer(bot, meshcat)
    with pytest.raises(SotError, match="visualizer already"):  # (Drake would end the process at Build())
        add_robot_visualizer(bot, meshcat)
    for position, radius in (([1.0, 2.0], 0.02), ([0.0, 0.0, float("nan")], 0.02), ([0.0, 0.0, 1.0], -1.0)):
        with pytest.raises(InvalidInput):
            add_target_marker(meshcat, "/target", position, radius)
    hand = MetaTaskKine6d("h", bot, "hand", "hand")
    add_target_marker(meshcat, "/hand", hand)
    with pytest.raises(SotError, match="marker already"):
        add_target_marker(meshcat, "/hand2", hand)
    with pytest.raises(InvalidInput, match="folder"):
        save_recording(visualizer, meshcat, tmp_path / "missing" / "recording.html")
    bot.builder.Build()


def test_attime_takes_a_command_or_a_pair():
    from sotdrake.sequencer import attime

    for command in ((lambda: None,), (lambda: None, "d", "x"), (lambda: None, 3)):
        with pytest.raises(InvalidInput, match="callable"):
            attime(1.0, command)


@pytest.mark.parametrize("field", ["swing_height", "feet_distance", "step_duration", "start_duration", "sole_length"])
def test_gait_lengths_and_durations_are_finite(field):
    from sotdrake.walking.gait import GaitParameters

    with pytest.raises(InvalidInput, match=field):
        GaitParameters(**{field: float("inf")})


@pytest.mark.parametrize("options", [
    {"sole_centre": (float("nan"), 0.0)}, {"sole_centre": (0.0, 0.0, 0.0)}, {"sole_centre": "ab"},
    {"horizon_steps": 4.5}, {"replan_steps": 2.0}, {"replan_steps": 6}, {"swing_height": "0.05"},
    {"step_duration": True}, {"single_support": 0.8}, {"swing_profile": None},
])
def test_gait_parameters_of_the_wrong_kind_are_refused_when_made(options):
    """A NaN sole centre made the CoM NaN; a fractional horizon failed at the first replan, mid-run."""
    from sotdrake.walking.gait import GaitParameters

    with pytest.raises(InvalidInput, match=f"GaitParameters.{next(iter(options))}"):
        GaitParameters(**options)


def test_a_robot_without_a_solver_is_named_before_the_run(tmp_path):
    from sotdrake import simulate

    builder = DiagramBuilder()
    robot(builder, load_robot(three_link(tmp_path / "arm.urdf")))
    with pytest.raises(StackError, match="control input is not connected"):
        simulate(builder.Build(), 0.01, progress=False)


@pytest.mark.parametrize("options", [
    {"velocity": (0.1, 0.0)}, {"velocity": "abc"}, {"then": (1.0, 0.0, 0.0)}, {"then": (-1.0, 0.0, 0.0, 0.0)},
    {"steps": (3,)}, {"steps": (2.5, 0.1)}, {"steps": (1e9, 0.1)}, {"steps": (-2, 0.1)}, {"gains": (1.0,)},
    {"gains": (float("nan"), 1.0)},
])
def test_the_walk_checks_its_commands_before_loading_anything(options):
    """A wrong shape used to end in a raw TypeError while unpacking; a billion steps in a list of that size."""
    from sotdrake.walking.controller import build_diagram

    with pytest.raises(InvalidInput, match="build_diagram"):
        build_diagram(**options)
