"""The hostile user's harness: a table of bad inputs and randomized runs, each attempt isolated.

Two kinds of attempt, each identified by an index:

* **bad inputs** (:func:`bad_inputs`): a call through the public API with a wrong value. Expected: a
  :class:`~sotdrake.exceptions.SotError` whose message names the argument, and the state (every
  entity's settings in the context and in its defaults, every discrete state, the time) unchanged.
* **randomized runs** (:func:`random_run`): the tutorial's graph (contacts on top, then a random
  subset and order of CoM, both hands, posture; random targets up to 5 m away, random gains in
  their accepted range at the control period ``dt``, random SVD threshold and damping) simulated for
  a short while. Expected: no process exit, no NaN, no frozen tick (a ``SolverKine`` failure that
  holds the device), each contact (ankle) within ``CONTACT_TOLERANCE`` of where it started at every
  tick, and, under ``SolverKine``, no joint beyond its position limits.

The attempts run in worker processes (``python -m tests.hostile worker KIND SOLVER INDICES DURATION DT``)
that print one JSON line when an attempt starts and one with its result. The parent
(:func:`run_attempts`) reads them; when a worker dies (a ``SystemExit``, an abort, a segfault) or
stays silent longer than ``timeout`` (a hang), the attempt in progress is recorded as such and a new
worker goes on from the next one; a worker is also replaced after ``ATTEMPTS_PER_WORKER`` attempts.
``bench/hostile.py`` runs the full table and ≥ 1000 runs; the test
suite a fast subset.
"""

from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, is_dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CONTACT_TOLERANCE = 1e-4  # m
#: Attempts a worker process runs before a fresh one takes over (bounds its memory).
ATTEMPTS_PER_WORKER = 100


# --- the fixture: the tutorial's graph with every task known to the solver ----------------------
@dataclass
class Fixture:
    solver: str
    diagram: object
    robot: object
    sot: object
    tasks: dict
    runner: object
    default_context: object

    @property
    def context(self):
        return self.runner.context


def build_fixture(solver: str = "cascade", dt: float = 1e-3) -> Fixture:
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake.interactive import Runner
    from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, MetaTaskKinePosture
    from sotdrake.robot import add_sot, talos
    from sotdrake.robots import TALOS_GRIPPERS

    builder = DiagramBuilder()
    robot = talos(builder, dt=dt)
    tasks = {
        "contactRF": MetaTaskKine6d("contactRF", robot, "RF", "right-ankle"),
        "contactLF": MetaTaskKine6d("contactLF", robot, "LF", "left-ankle"),
        "com": MetaTaskKineCom(robot),
        "rh": MetaTaskKine6d("rh", robot, "rh", "right-wrist"),
        "lh": MetaTaskKine6d("lh", robot, "lh", "left-wrist"),
        "posture": MetaTaskKinePosture(robot),
        "head": MetaTaskKine6d("head", robot, "head", "gaze", pd=True),
    }
    for name in ("contactRF", "contactLF"):
        tasks[name].gain.setConstant(10.0)
    sot = add_sot(robot, solver=solver)
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))
    sot.addContact(tasks["contactRF"])
    sot.addContact(tasks["contactLF"])
    sot.push(tasks["com"].task.name)
    sot.push(tasks["rh"].task.name)
    diagram = builder.Build()
    runner = Runner(diagram, robot.dt)
    return Fixture(solver, diagram, robot, sot, tasks, runner, diagram.CreateDefaultContext())


# --- the state, for "unchanged" ---------------------------------------------------------------
def _plain(value):
    """A comparable, JSON-able image of a settings value."""
    from pydrake.math import RigidTransform

    if isinstance(value, np.ndarray):
        return ["array", list(value.shape), value.astype(float).ravel().tolist() if value.dtype != object else repr(value)]
    if isinstance(value, RigidTransform):
        return ["X", value.GetAsMatrix4().ravel().tolist()]
    if is_dataclass(value):
        return [type(value).__name__, {k: _plain(v) for k, v in vars(value).items()}]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return repr(value)


def fingerprint(fx: Fixture) -> str:
    """Every entity's settings (context and defaults), every discrete state, and the time."""
    from sotdrake.entity import Entity

    context = fx.context
    image = {"time": context.get_time()}
    for system in fx.diagram.GetSystems():
        own = system.GetMyContextFromRoot(context)
        entry = {"discrete": [own.get_discrete_state(i).get_value().tolist()
                              for i in range(own.num_discrete_state_groups())]}
        if isinstance(system, Entity):
            entry["settings"] = _plain(system.settings(context))
            entry["defaults"] = _plain(system.settings())
        image[system.get_name()] = entry
    return json.dumps(image, sort_keys=True, default=repr)


# --- the table of bad inputs ------------------------------------------------------------------
NAN, INF = float("nan"), float("inf")
#: Values a number argument must refuse (besides its own range).
BAD_NUMBERS = [NAN, INF, -INF, 1e300, -1e300, "1.0", None, [1.0], True, complex(1, 1), 10**400]


def _numbers(label: str, call: Callable, extra=(), skip=()) -> list[tuple[str, Callable]]:
    values = [*(v for v in BAD_NUMBERS if v not in skip), *extra]
    return [(f"{label}({value!r:.30})", (lambda fx, v=value: call(fx, v))) for value in values]


def _urdf_with(limit: str) -> str:
    return ('<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="revolute">'
            f'<parent link="a"/><child link="b"/><axis xyz="0 0 1"/>{limit}</joint></robot>')


def _loader_with_bad_urdf(fx) -> None:
    """The loader on a TALOS URDF whose first joint has lower > upper (Drake aborts on it)."""
    import re
    import tempfile

    import sotdrake.robots.loader as loader
    from sotdrake.robots import load_talos

    text = loader.urdf_path("talos", "reduced").read_text()
    text = re.sub(r'lower="([^"]+)" upper="([^"]+)"', r'lower="3.0" upper="-3.0"', text, count=1)
    path = Path(tempfile.mkdtemp()) / "talos_reduced.urdf"
    path.write_text(text)
    original = loader.urdf_path
    loader.urdf_path = lambda name, variant=None: path
    try:
        load_talos("reduced")
    finally:
        loader.urdf_path = original


def _builder():
    from pydrake.systems.framework import DiagramBuilder

    return DiagramBuilder()


def _other_robot_task():
    """A right-hand task ``taskrh`` of another robot (same name as the fixture's)."""
    from sotdrake.meta_tasks import MetaTaskKine6d
    from sotdrake.robot import add_sot, talos

    other = talos(_builder())
    task = MetaTaskKine6d("rh", other, "rh", "right-wrist")
    add_sot(other)
    return task


def _file(name: str, text: str) -> str:
    import tempfile

    path = Path(tempfile.mkdtemp()) / name
    path.write_text(text)
    return str(path)


def _new_robot():
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake.robot import talos

    return talos(DiagramBuilder())


def _physical():
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake.physics import add_physical_talos

    if not hasattr(_physical, "cache"):
        _physical.cache = add_physical_talos(DiagramBuilder())
    return _physical.cache


def bad_inputs() -> list[tuple[str, Callable]]:
    """The table: ``(label, call(fixture))``, each call a bad input."""
    from sotdrake.gains import GainHyperbolic
    from sotdrake.interactive import Runner
    from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, gotoNd
    from sotdrake.physics import Push, add_physical_talos, set_pd_gains
    from sotdrake.robot import add_sot, talos
    from sotdrake.robots.urdf_checks import check_urdf_limits
    from sotdrake.sequencer import attime

    def T(fx, name):
        return fx.tasks[name]

    def c(fx):
        return fx.context

    table: list[tuple[str, Callable]] = []
    add = table.extend
    # gains
    add(_numbers("gain.setConstant", lambda fx, v: T(fx, "rh").gain.setConstant(v, c(fx)), [-1.0, 2000.0, 1e5, 1e308]))
    add(_numbers("gain.set(λ0)", lambda fx, v: T(fx, "rh").gain.set(v, 0.9, 1.0, c(fx)), [0.5, 3000.0]))
    add(_numbers("gain.set(λ∞)", lambda fx, v: T(fx, "rh").gain.set(4.0, v, 1.0, c(fx)), [-0.1, 5.0]))
    add(_numbers("gain.set(slope)", lambda fx, v: T(fx, "rh").gain.set(4.0, 0.9, v, c(fx)), [-1.0, 1e12]))
    add(_numbers("gain.setByPoint(λ0)", lambda fx, v: T(fx, "rh").gain.setByPoint(v, 0.9, 0.01, 0.9, c(fx)), [0.1, 2500.0]))
    add(_numbers("gain.setByPoint(e_ref)", lambda fx, v: T(fx, "rh").gain.setByPoint(4.9, 0.9, v, 0.9, c(fx)), [0.0, -1.0, 1e-12, 1e6]))
    add(_numbers("gain.setByPoint(p)", lambda fx, v: T(fx, "rh").gain.setByPoint(4.9, 0.9, 0.01, v, c(fx)), [0.0, 1.0, 1.5, -0.5]))
    add(_numbers("GainHyperbolic.set(λ0)", lambda fx, v: GainHyperbolic("g", 1e-3).set(v, 1.0, 1.0, 0.0), [5000.0]))
    add(_numbers("GainHyperbolic.set(decal0)", lambda fx, v: GainHyperbolic("g", 1e-3).set(4.0, 1.0, 1.0, v), [1e6]))
    table.append(("gain.setCoefficients('abc')", lambda fx: T(fx, "rh").gain.setCoefficients("abc", c(fx))))
    # solver settings
    add(_numbers("sot.setThreshold", lambda fx, v: fx.sot.setThreshold(v, c(fx)), [-1.0, 2.0]))
    add(_numbers("sot.setDamping", lambda fx, v: fx.sot.setDamping(v, c(fx)), [-1.0, 1e5]))
    # the PD task
    add(_numbers("taskhead.setBeta", lambda fx, v: T(fx, "head").task.setBeta(v, c(fx)), [-1.0, 1.0, 1e3]))
    # targets
    add(_numbers("gotoNd(rh, (x, 0, 1))", lambda fx, v: gotoNd(T(fx, "rh"), [v, 0.0, 1.0], context=c(fx)), [101.0, -1e5]))
    add(_numbers("gotoNd(rh, 6D roll)", lambda fx, v: gotoNd(T(fx, "rh"), [0.5, 0.0, 1.0, v, 0.0, 0.0], context=c(fx)), [7.0, -1e4]))
    add(_numbers("gotoNd(com, (0, 0, z))", lambda fx, v: gotoNd(T(fx, "com"), [0.0, 0.0, v], context=c(fx)), [1e3]))
    add(_numbers("gotoNd(rh, gain=λ)", lambda fx, v: gotoNd(T(fx, "rh"), [0.5, -0.2, 1.0], gain=v, context=c(fx)), [2000.0, -1.0],
                 skip=(None, [1.0])))
    add(_numbers("featureDes.setVelocity", lambda fx, v: T(fx, "rh").featureDes.setVelocity([v, 0, 0, 0, 0, 0], c(fx)), [1e3]))
    add(_numbers("com featureDes.setVelocity", lambda fx, v: T(fx, "com").featureDes.setVelocity([0.0, v, 0.0], c(fx)), [1e3]))
    add(_numbers("posture.setPosture(q[10])", lambda fx, v: T(fx, "posture").feature.setPosture(_with(fx, 10, v), c(fx)), [1e3]))
    add(_numbers("device.set_position(q[10])", lambda fx, v: fx.robot.device.set_position(c(fx), _with(fx, 10, v)), [1e3]))
    table.append(("device.set_position(zero quaternion)", lambda fx: fx.robot.device.set_position(c(fx), _with(fx, slice(0, 4), 0.0))))
    table.append(("posture.setPosture(zero quaternion)",
                  lambda fx: T(fx, "posture").feature.setPosture(_with(fx, slice(0, 4), 0.0), c(fx))))
    table.append(("posture.setPosture(quaternion of norm 2)",
                  lambda fx: T(fx, "posture").feature.setPosture(_with(fx, slice(0, 4), 1.0), c(fx))))
    for label, value in [("[]", []), ("(1, 2)", [1.0, 2.0]), ("4 numbers", [1.0, 2.0, 3.0, 4.0]),
                         ("'abc'", "abc"), ("None", None), ("{}", {}), ("[[1, 2, 3]]", [[1.0, 2.0, 3.0]]),
                         ("zeros(4, 4)", np.zeros((4, 4))), ("scaled rotation", np.diag([2.0, 2.0, 2.0, 1.0])),
                         ("reflection", np.diag([1.0, 1.0, -1.0, 1.0])), ("4x4 far", np.r_[np.c_[np.eye(3), [1e4, 0, 0]], [[0, 0, 0, 1]]]),
                         ("object()", object())]:
        table.append((f"gotoNd(rh, {label})", lambda fx, v=value: gotoNd(T(fx, "rh"), v, context=c(fx))))
        table.append((f"rh.featureDes.setPosition({label})", lambda fx, v=value: T(fx, "rh").featureDes.setPosition(v, c(fx))))
    for value in ["", "2", "1111111", "abc", 111, ["1"], 1.5]:
        table.append((f"gotoNd(rh, selec={value!r})", lambda fx, v=value: gotoNd(T(fx, "rh"), [0.5, -0.2, 1.0], v, context=c(fx))))
        table.append((f"feature.selec({value!r})", lambda fx, v=value: T(fx, "rh").feature.selec(v, c(fx))))
    for value in [[], [1.0, 2.0], [1, 2, 3, 4, 5], ["a"], [NAN], [1e308], [3000.0], [4.9, 0.9, 0.01, 1.0],
                  [4.9, 0.9, 0.0, 0.5], [0.9, 4.9, 1.0], [-1.0], "abc", {"a": 1}, [4.9, 0.9, 1e-12, 0.5]]:
        table.append((f"gotoNd(rh, gain={value!r})", lambda fx, v=value: gotoNd(T(fx, "rh"), [0.5, -0.2, 1.0], gain=v, context=c(fx))))
    table.append(("gotoNd('rh', ...)", lambda fx: gotoNd("rh", [0.5, -0.2, 1.0], context=c(fx))))
    table.append(("gotoNd(posture, ...)", lambda fx: gotoNd(T(fx, "posture"), [0.5, -0.2, 1.0], context=c(fx))))
    for value in [[1.0, 2.0], [NAN, 0, 1], "abc", None, [1e300, 0, 0]]:
        table.append((f"com.featureDes.setReference({value!r})", lambda fx, v=value: T(fx, "com").featureDes.setReference(v, c(fx))))
    for value in [np.zeros((4, 4)), [1e300, 0, 0], "abc", np.diag([1.0, 1.0, -1.0, 1.0])]:
        table.append((f"feature.setOpmodif({value!r:.30})", lambda fx, v=value: T(fx, "rh").feature.setOpmodif(v, c(fx))))
    for value in ["nope", None, 5]:
        table.append((f"feature.frame({value!r})", lambda fx, v=value: T(fx, "rh").feature.frame(v, c(fx))))
    for value in [[1.0], np.full(5, np.nan), "abc", None]:
        table.append((f"posture.setPosture({value!r:.30})", lambda fx, v=value: T(fx, "posture").feature.setPosture(v, c(fx))))
    # the stack
    for value in ["nope", "", None, 5, ["taskrh"], "taskcom", "taskcontactRF", 1.5]:
        table.append((f"sot.push({value!r})", lambda fx, v=value: fx.sot.push(v, c(fx))))
        table.append((f"sot.remove({value!r})", lambda fx, v=value: fx.sot.remove(v if v != "taskcom" else "taskposture", c(fx))))
    for label, call in [
        ("sot.up(top)", lambda fx: fx.sot.up("taskcom", c(fx))),
        ("sot.down(bottom)", lambda fx: fx.sot.down("taskrh", c(fx))),
        ("sot.up('nope')", lambda fx: fx.sot.up("nope", c(fx))),
        ("sot.down(not in stack)", lambda fx: fx.sot.down("taskposture", c(fx))),
        ("sot.addContact(duplicate)", lambda fx: fx.sot.addContact(T(fx, "contactRF"), c(fx))),
        ("sot.addContact(in stack)", lambda fx: fx.sot.addContact("taskcom", c(fx))),
        ("sot.addContact(None)", lambda fx: fx.sot.addContact(None, c(fx))),
        ("sot.addContact('nope')", lambda fx: fx.sot.addContact("nope", c(fx))),
        ("sot.rmContact(not a contact)", lambda fx: fx.sot.rmContact("taskcom", c(fx))),
        ("sot.rmContact(5)", lambda fx: fx.sot.rmContact(5, c(fx))),
    ]:
        table.append((label, call))
    for label, value in [("3 booleans", [True] * 3), ("floats", np.ones(38)), ("none selected", np.zeros(38, bool)),
                         ("'abc'", "abc"), ("5", 5)]:
        table.append((f"sot.setControlSelection({label})", lambda fx, v=value: fx.sot.setControlSelection(v, c(fx))))
    # the runner
    add(_numbers("runner.go(duration)", lambda fx, v: fx.runner.go(v), [-1.0, 1e7], skip=(None,)))  # None: until Ctrl-C
    add(_numbers("runner.go(0.01, chunk)", lambda fx, v: fx.runner.go(0.01, chunk=v), [0.0, -0.1, 1e-9, 1e3]))
    add(_numbers("runner.step", lambda fx, v: fx.runner.step(v), [-1, 1.5, 10**12]))
    add(_numbers("runner.advance_to", lambda fx, v: fx.runner.advance_to(v), [-1.0, 1e9]))
    add(_numbers("Runner(dt)", lambda fx, v: Runner(fx.diagram, v), [0.0, -1e-3, 5.0]))
    # the sequencer
    add(_numbers("attime(t)", lambda fx, v: attime(v, lambda: fx.sot.push("taskposture")), [-1.0]))
    table.append(("attime(t, context= command)", lambda fx: attime(1.0, lambda: fx.sot.push("taskposture", c(fx)))))
    table.append(("attime(t, set_position)", lambda fx: attime(
        1.0, lambda: fx.robot.device.set_position(c(fx), fx.robot.device.initial_position))))
    table.append(("attime(t, no command)", lambda fx: attime(1.0, lambda: None)))
    table.append(("attime(t, 'not callable')", lambda fx: attime(1.0, "push")))
    table.append(("attime(t, keep())", lambda fx: attime(1.0, lambda: T(fx, "rh").keep())))
    # building (fresh builders: the fixture's diagram is built)
    for label, call in [
        ("MetaTaskKine6d(unknown op point)", lambda fx: MetaTaskKine6d("x", _new_robot(), "x", "nope")),
        ("MetaTaskKine6d(duplicate name)", lambda fx: (lambda r: (MetaTaskKine6d("x", r, "x", "right-wrist"),
                                                                  MetaTaskKine6d("x", r, "x", "left-wrist")))(_new_robot())),
        ("MetaTaskKineCom twice", lambda fx: (lambda r: (MetaTaskKineCom(r), MetaTaskKineCom(r)))(_new_robot())),
        ("MetaTaskKine6d after Build", lambda fx: MetaTaskKine6d("late", fx.robot, "late", "right-wrist")),
        ("talos(variant='nope')", lambda fx: talos(__import__("pydrake.systems.framework", fromlist=["x"]).DiagramBuilder(), "nope")),
        ("talos(variant=5)", lambda fx: talos(__import__("pydrake.systems.framework", fromlist=["x"]).DiagramBuilder(), 5)),
        ("talos(dt=0)", lambda fx: talos(__import__("pydrake.systems.framework", fromlist=["x"]).DiagramBuilder(), dt=0.0)),
        ("talos(dt=nan)", lambda fx: talos(__import__("pydrake.systems.framework", fromlist=["x"]).DiagramBuilder(), dt=NAN)),
        ("add_sot(solver='x')", lambda fx: add_sot(_new_robot(), solver="x")),
        ("add_sot twice", lambda fx: (lambda r: (add_sot(r), add_sot(r, "sot2")))(_new_robot())),
        ("add_sot(damping=-1)", lambda fx: add_sot(_new_robot(), damping=-1.0)),
        ("add_sot(svd_threshold=nan)", lambda fx: add_sot(_new_robot(), svd_threshold=NAN)),
        ("add_sot(qp_solver='x')", lambda fx: add_sot(_new_robot(), solver="hqp", qp_solver="x")),
        ("loader: URDF with lower > upper", _loader_with_bad_urdf),
    ]:
        table.append((label, call))
    for label, limit in [("lower > upper", '<limit lower="1" upper="-1" effort="1" velocity="1"/>'),
                         ("lower 'abc'", '<limit lower="abc" upper="1" effort="1" velocity="1"/>'),
                         ("upper NaN", '<limit lower="0" upper="nan" effort="1" velocity="1"/>'),
                         ("negative effort", '<limit lower="0" upper="1" effort="-1" velocity="1"/>'),
                         ("negative velocity", '<limit lower="0" upper="1" effort="1" velocity="-2"/>')]:
        text = _urdf_with(limit)
        table.append((f"check_urdf_limits({label})", lambda fx, t=text: check_urdf_limits(t)))
    table.append(("check_urdf_limits(not XML)", lambda fx: check_urdf_limits("<robot>")))
    table.append(("check_urdf_limits(<sdf>)", lambda fx: check_urdf_limits("<sdf/>")))
    # physics
    add(_numbers("add_physical_talos(time_step)", lambda fx, v: add_physical_talos(
        __import__("pydrake.systems.framework", fromlist=["x"]).DiagramBuilder(), time_step=v), [0.0, -1e-3, 1.0]))
    for label, value in [("'SAP'", "SAP"), ("None", None), ("['sap']", ["sap"])]:
        table.append((f"add_physical_talos(contact_solver={label})", lambda fx, v=value: add_physical_talos(
            __import__("pydrake.systems.framework", fromlist=["x"]).DiagramBuilder(), contact_solver=v)))
    add(_numbers("set_pd_gains(stiffness)", lambda fx, v: set_pd_gains(_physical().plant, v, 0.05), [0.0, -1.0, 1e9]))
    add(_numbers("Push(force x)", lambda fx, v: Push(_physical().plant, "torso_2_link", [v, 0.0, 0.0], 1.0, 0.1), [1e6]))
    for label, args in [("body 'nope'", ("nope", [1.0, 0, 0], 1.0, 0.1)), ("body None", (None, [1.0, 0, 0], 1.0, 0.1)),
                        ("duration 0", ("torso_2_link", [1.0, 0, 0], 1.0, 0.0)), ("start -1", ("torso_2_link", [1.0, 0, 0], -1.0, 0.1)),
                        ("start 'a'", ("torso_2_link", [1.0, 0, 0], "a", 0.1)), ("force 2D", ("torso_2_link", [1.0, 0], 1.0, 0.1))]:
        table.append((f"Push({label})", lambda fx, a=args: Push(_physical().plant, *a)))
    # robots, builders and the simulation
    from pydrake.math import RigidTransform

    from sotdrake.dynamics.trajectories import hold_move_hold
    from sotdrake.robot import Robot
    from sotdrake.robots import load_robot, load_talos
    from sotdrake.simulation import simulate

    for label, call in [
        ("talos twice in one builder", lambda fx: (lambda b: (talos(b), talos(b)))(_builder())),
        ("sot.push(another robot's task)", lambda fx: fx.sot.push(_other_robot_task(), c(fx))),
        ("sot.addContact(another robot's task)", lambda fx: fx.sot.addContact(_other_robot_task(), c(fx))),
        ("gotoNd(rh, RigidTransform scaled)", lambda fx: gotoNd(T(fx, "rh"), RigidTransform(np.diag([2.0, 2.0, 2.0, 1.0])), context=c(fx))),
        ("gotoNd(rh, RigidTransform rank 2)", lambda fx: gotoNd(T(fx, "rh"), RigidTransform(np.diag([1.0, 1.0, 0.0, 1.0])), context=c(fx))),
        ("Robot(q0 quaternion of norm 2)", lambda fx: Robot(_builder(), load_talos("reduced"), q0=_with(fx, 0, 2.0))),
        ("Robot(q0 joint 1e6 rad)", lambda fx: Robot(_builder(), load_talos("reduced"), q0=_with(fx, 10, 1e6))),
        ("Robot(q0 of the wrong size)", lambda fx: Robot(_builder(), load_talos("reduced"), q0=np.zeros(5))),
        ("hold_move_hold(t, t)", lambda fx: hold_move_hold(1.0, 1.0, [0.0], [1.0])),
        ("hold_move_hold(t1 < t0)", lambda fx: hold_move_hold(1.0, 0.5, [0.0], [1.0])),
        ("hold_move_hold(sizes differ)", lambda fx: hold_move_hold(0.0, 1.0, [0.0], [1.0, 2.0])),
        ("hold_move_hold(NaN target)", lambda fx: hold_move_hold(0.0, 1.0, [0.0], [NAN])),
        ("simulate(diagram, inf)", lambda fx: simulate(fx.diagram, INF, progress=False)),
        ("simulate(diagram, '1')", lambda fx: simulate(fx.diagram, "1", progress=False)),
        ("talos(dt='0.001')", lambda fx: talos(_builder(), dt="0.001")),
        ("posture.selectDof(1.5)", lambda fx: T(fx, "posture").feature.selectDof(1.5, True, c(fx))),
        ("posture.selectDof(-1)", lambda fx: T(fx, "posture").feature.selectDof(-1, True, c(fx))),
        ("posture.selectDof(3, 'yes')", lambda fx: T(fx, "posture").feature.selectDof(3, "yes", c(fx))),
        ("load_robot(missing file)", lambda fx: load_robot(str(ROOT / "no_such_robot.urdf"))),
        ("load_robot(not XML)", lambda fx: load_robot(_file("broken.urdf", "<robot name='r'><link name='a'/>"))),
    ]:
        table.append((label, call))
    if True:  # SolverKine-only commands: the fixture's solver must be a SolverKine
        add(_numbers("solver.setPositionMargin", lambda fx, v: _kine(fx).setPositionMargin(v, c(fx)), [-1.0, 1.0]))
        add(_numbers("solver.setBaseVelocityLimit(angular)", lambda fx, v: _kine(fx).setBaseVelocityLimit(v, 1.0, c(fx)), [0.0, -1.0, 1e3]))
        add(_numbers("solver.setBaseVelocityLimit(linear)", lambda fx, v: _kine(fx).setBaseVelocityLimit(1.0, v, c(fx)), [0.0, 1e3]))
        add(_numbers("solver.setAccelerationLimit", lambda fx, v: _kine(fx).setAccelerationLimit(v, c(fx)), [0.0, -1.0, 1e7],
                     skip=(INF, None, [1.0])))  # (inf: no limit; None: none; [1.0]: one number for every joint)
        for value in ["nope", None, 5]:
            table.append((f"solver.setSolver({value!r})", lambda fx, v=value: _kine(fx).setSolver(v, c(fx))))
    return table


def _with(fx: Fixture, index, value):
    """The initial ``q`` with ``q[index] = value`` when ``value`` is a real number, else ``value``."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        q = np.array(fx.robot.device.initial_position, dtype=float)
        q[index] = value
        return q
    return value


def _kine(fx: Fixture):
    """The fixture's solver as a SolverKine (the cascade fixture builds one on the side)."""
    from sotdrake.solvers import SolverKine

    if isinstance(fx.sot, SolverKine):
        return fx.sot
    raise NotImplementedError("SolverKine command on the cascade fixture")


def bad_input_solver(label: str) -> str:
    """The fixture a bad input needs."""
    return "hqp" if label.startswith("solver.") else "cascade"


def attempt_bad_input(fx: Fixture, label: str, call: Callable) -> dict:
    from sotdrake.exceptions import SotError

    before = fingerprint(fx)
    result = {"label": label}
    try:
        call(fx)
        result["status"] = "accepted"
    except SotError as error:
        result["status"] = "sot_error"
        result["message"] = str(error)[:300]
    except Exception as error:
        result["status"] = "other_error"
        result["message"] = f"{type(error).__name__}: {str(error)[:300]}"
    result["unchanged"] = fingerprint(fx) == before
    return result


# --- randomized runs --------------------------------------------------------------------------
def _log_uniform(rng, low: float, high: float) -> float:
    return float(np.exp(rng.uniform(np.log(low), np.log(high))))


def random_run(fx: Fixture, seed: int, duration: float = 0.1) -> dict:
    """One randomized run on the fixture (see the module docstring); the fixture's context is reset
    to its defaults first, and every setting goes through the public commands with ``context=``."""
    from sotdrake.meta_tasks import gotoNd

    rng = np.random.default_rng(seed)
    runner, sot, robot = fx.runner, fx.sot, fx.robot
    simulator = runner.simulator
    context = simulator.get_mutable_context()
    context.SetTimeStateAndParametersFrom(fx.default_context)
    description: dict = {"seed": seed, "solver": fx.solver}
    for name in ("contactRF", "contactLF"):
        gain = _log_uniform(rng, 10.0, 1.0 / robot.dt)
        fx.tasks[name].gain.setConstant(gain, context)
    sot.clear(context)
    mode = "addContact" if rng.random() < 0.5 else "push"
    if mode == "push":  # the right foot as the stack's top task (the last contact stays a contact)
        sot.rmContact(fx.tasks["contactRF"], context)
        sot.push(fx.tasks["contactRF"].task.name, context)
    candidates = ["com", "rh", "lh", "posture", "head"]
    chosen = [str(n) for n in rng.permutation(candidates)[: rng.integers(1, len(candidates) + 1)]]
    for name in chosen:
        meta = fx.tasks[name]
        if rng.random() < 0.6:  # constant, or setByPoint(λ0, λ∞, e_ref, p), all with λ·dt < 2
            gain = [_log_uniform(rng, 0.01, 1.9 / robot.dt)]
        else:
            gain0 = _log_uniform(rng, 1.0, 1.9 / robot.dt)
            gain = [gain0, float(rng.uniform(0.0, gain0)), _log_uniform(rng, 1e-3, 1.0), float(rng.uniform(0.05, 0.95))]
        if name in ("rh", "lh"):
            target = rng.uniform(-5.0, 5.0, size=3) + [0.0, 0.0, 1.0]
            position = list(target) + (list(rng.uniform(-np.pi, np.pi, 3)) if rng.random() < 0.3 else [])
            gotoNd(meta, position, "111111" if len(position) == 6 else "111", gain, context=context)
        elif name == "com":
            gotoNd(meta, rng.uniform(-2.0, 2.0, size=3) + [0.0, 0.0, 0.8], "111", gain, context=context)
        else:
            meta.gain.setConstant(gain[0], context)
        sot.push(meta.task.name, context)
    if fx.solver == "cascade":
        sot.setThreshold(_log_uniform(rng, 1e-6, 1e-2), context)
        sot.setDamping(0.0 if rng.random() < 0.5 else _log_uniform(rng, 1e-8, 1e-2), context)
    description.update(mode=mode, stack=sot.stack(context), contacts=sot.contacts(context))
    simulator.Initialize()
    q0 = robot.device.position(context)
    start = {op: robot.dynamic.pose_at(op, q0).translation() for op in ("left-ankle", "right-ankle")}
    lower, upper = robot.model.plant.GetPositionLowerLimits(), robot.model.plant.GetPositionUpperLimits()
    drift, violation, finite, scale, frozen, failure = 0.0, 0.0, True, 1.0, 0, ""
    own = sot.GetMyContextFromRoot(context)
    diagnostics = sot.GetOutputPort("diagnostics") if sot.HasOutputPort("diagnostics") else None
    error = None
    try:
        for k in range(1, max(1, round(duration / robot.dt)) + 1):
            if diagnostics is not None and diagnostics.Eval(own).failure:  # the device holds: a frozen tick
                frozen += 1
                failure = failure or diagnostics.Eval(own).failure[:200]
            scale = min(scale, float(sot.GetOutputPort("velocity_scale").Eval(own)[0]))
            simulator.AdvanceTo(k * robot.dt)
            q = robot.device.position(context)
            if not np.all(np.isfinite(q)):
                finite = False
                break
            for op, p0 in start.items():
                drift = max(drift, float(np.linalg.norm(robot.dynamic.pose_at(op, q).translation() - p0)))
            violation = max(violation, float(np.max(np.maximum(lower - q, q - upper))))
    except Exception as exc:
        error = f"{type(exc).__name__}: {str(exc)[:200]}"
    description.update(contact_drift_m=drift, limit_violation=max(violation, 0.0), finite=finite,
                       min_velocity_scale=scale, frozen_ticks=frozen, failure=failure, error=error,
                       time=context.get_time(), dt=robot.dt)
    return description


# --- the worker and the parent ----------------------------------------------------------------
def worker(kind: str, solver: str, indices: list[int], duration: float, dt: float = 1e-3) -> None:
    """Run the attempts ``indices`` of ``kind`` on one fixture (control period ``dt``), printing
    JSON lines."""
    import logging

    logging.disable(logging.WARNING)
    fx = None if kind == "crash" else build_fixture(solver, dt)
    table = bad_inputs() if kind == "bad" else None
    for i in indices:
        print(json.dumps({"start": i}), flush=True)
        if kind == "bad":
            label, call = table[i]
            result = attempt_bad_input(fx, label, call)
            if result["status"] == "accepted" or not result["unchanged"]:
                fx = build_fixture(solver, dt)  # the next attempt starts clean
        elif kind == "crash":  # the harness' own check: this attempt ends the process
            os._exit(3) if i % 2 else os.abort()
        else:
            result = random_run(fx, i, duration)
        result["worker_max_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # (Linux: kB)
        print(json.dumps({"done": i, "result": result}, default=repr), flush=True)


def run_attempts(kind: str, solver: str, indices: list[int], duration: float = 0.1,
                 timeout: float = 300.0, log: Path | None = None, dt: float = 1e-3,
                 per_worker: int = ATTEMPTS_PER_WORKER) -> dict[int, dict]:
    """Results by index; an attempt whose worker died is ``{"status": "process_exit", ...}``, one
    that stayed silent longer than ``timeout`` seconds ``{"status": "hang"}``. With ``log``, each
    result is also appended to that file as a JSON line as it comes. A worker runs at most
    ``per_worker`` attempts, then a fresh one goes on (each diagram built keeps ~3 MB in a process:
    recycling bounds the workers' memory)."""

    def record(index: int, result: dict) -> None:
        results[index] = result
        if log is not None:
            with open(log, "a") as f:
                f.write(json.dumps({"kind": kind, "solver": solver, "dt": dt, "index": index, "result": result},
                                   default=repr) + "\n")

    import queue
    import threading

    results: dict[int, dict] = {}
    pending = list(indices)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    while pending:
        batch = pending[:per_worker]
        process = subprocess.Popen(
            [sys.executable, "-m", "tests.hostile", "worker", kind, solver, json.dumps(batch), str(duration), str(dt)],
            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        lines: queue.Queue = queue.Queue()

        def read(stream=process.stdout, sink=lines):
            for line in stream:
                sink.put(line)
            sink.put(None)

        threading.Thread(target=read, daemon=True).start()
        current, started = None, False
        while True:
            try:  # the fixture takes a while to build: the first line gets a longer grace
                line = lines.get(timeout=timeout if started else timeout + 300.0)
            except queue.Empty:
                process.kill()
                if current is not None:
                    record(current, {"status": "hang"})
                break
            if line is None:
                break
            started = True
            message = json.loads(line)
            if "start" in message:
                current = message["start"]
            elif "done" in message:
                record(message["done"], message["result"])
                current = None
        process.wait()
        if current is not None and current not in results:
            record(current, {"status": "process_exit", "returncode": process.returncode})
        if current is None and not any(i in results for i in batch):  # died building the fixture: nothing to go on with
            for i in pending:
                if i not in results:
                    record(i, {"status": "worker_failed", "returncode": process.returncode})
        pending = [i for i in pending if i not in results]
    return results


if __name__ == "__main__":
    if sys.argv[1] == "worker":
        worker(sys.argv[2], sys.argv[3], json.loads(sys.argv[4]), float(sys.argv[5]), float(sys.argv[6]))
