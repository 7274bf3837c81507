"""What the user sees of a target: the marker is drawn where the task's desired value is in the
Context (it follows ``gotoNd`` at build time, in ``attime`` and from the live channel), the point the
task controls is drawn too, the summary's error is against the last target, and the README's first
stack shows its target on screen at the recording's last frame."""

from __future__ import annotations

import functools
import http.server
import shutil
import threading

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake import MetaTaskKine6d, add_sot, add_target_marker, attime, gotoNd, start_meshcat, talos
from sotdrake.live.grammar import parse_command
from sotdrake.live.server import apply
from sotdrake.live.vocabulary import Vocabulary
from sotdrake.scenarios import talos_appli
from sotdrake.target_marker import TARGET_COLOR, TargetMarker
from tests.test_readme import first_stack_code

GRIPPER = RigidTransform([0.0, 0.0, -0.2])  # the README's point between the gripper's fingers


class FakeMeshcat:
    """Records what a marker draws: the last transform and visibility of every path."""

    def __init__(self):
        self.transforms: dict[str, list[tuple[float | None, np.ndarray]]] = {}
        self.objects: set[str] = set()
        self.visible: dict[str, bool] = {}

    def SetObject(self, path, shape, rgba=None):
        self.objects.add(path)

    def SetLineSegments(self, path, start, end, line_width=1.0, rgba=None):
        self.objects.add(path)

    def SetTransform(self, path, X, time_in_recording=None):
        self.transforms.setdefault(path, []).append((time_in_recording, np.array(X.translation())))

    def SetProperty(self, path, name, value, time_in_recording=None):
        self.visible[path] = value

    def last(self, path: str) -> np.ndarray:
        return self.transforms[path][-1][1]


def hand_diagram(meshcat):
    """TALOS, the waist held, a gripper point driven to a target; the marker on the hand task."""
    builder = DiagramBuilder()
    robot = talos(builder)
    waist = MetaTaskKine6d("waist", robot, "waist", robot.OperationalPointsMap["waist"])
    hand = MetaTaskKine6d("rh", robot, "rh", robot.OperationalPointsMap["right-wrist"])
    hand.opmodif = GRIPPER
    gotoNd(hand, (0.4, -0.4, 0.9), "111", 5.0)
    sot = add_sot(robot)
    sot.push(waist.task.name)
    sot.push(hand.task.name)
    marker = add_target_marker(meshcat, "/target", hand)
    return builder, hand, marker


def test_the_marker_draws_the_target_and_the_controlled_point():
    meshcat = FakeMeshcat()
    builder, hand, marker = hand_diagram(meshcat)
    assert isinstance(marker, TargetMarker) and marker.get_name() == "markerrh"
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.Initialize()  # the initialization publish draws both
    context = simulator.get_context()
    own = marker.GetMyContextFromRoot(context)
    np.testing.assert_allclose(marker.GetOutputPort("target_position").Eval(own), [0.4, -0.4, 0.9])
    np.testing.assert_allclose(meshcat.last("/target/target"), [0.4, -0.4, 0.9])
    # The point is the wrist moved by opmodif (into the gripper), not the wrist joint's origin.
    point = hand.current_pose(context).translation()
    np.testing.assert_allclose(marker.GetOutputPort("point_position").Eval(own), point, atol=1e-12)
    np.testing.assert_allclose(meshcat.last("/target/point"), point, atol=1e-12)
    wrist = hand.dyn.GetOutputPort("rh").Eval(hand.dyn.GetMyContextFromRoot(context)).translation()
    assert np.linalg.norm(point - wrist) == pytest.approx(0.2)
    assert meshcat.visible["/target/point"] is True
    assert {"/target/target/sphere", "/target/target/crosshair", "/target/point"} <= meshcat.objects


def test_the_marker_follows_gotoNd_in_attime_and_is_recorded_at_its_time():
    meshcat = FakeMeshcat()
    builder, hand, marker = hand_diagram(meshcat)
    attime(0.5, lambda: gotoNd(hand, (0.45, -0.3, 0.95), "111", 5.0), "a new target")
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(1.0)
    recorded = meshcat.transforms["/target/target"]
    before = [p for t, p in recorded if t is not None and t < 0.5]
    after = [p for t, p in recorded if t is not None and t > 0.5 + 1e-9]
    assert before and after
    np.testing.assert_allclose(before[-1], [0.4, -0.4, 0.9])
    np.testing.assert_allclose(after[-1], [0.45, -0.3, 0.95])


def test_the_marker_follows_gotoNd_from_the_live_channel():
    """The tutorial's diagram as ``talos_appli.py --live`` builds it; the command as the live shell
    sends it, applied to the running context as the live runner does."""
    appli = talos_appli
    handles = appli.build_diagram(start_meshcat(), push_time=0.0)
    simulator = Simulator(handles.diagram)
    simulator.AdvanceTo(0.05)
    vocabulary = Vocabulary(handles.diagram, handles)
    marker = handles.diagram.GetSubsystemByName("markerrh")
    own = marker.GetMyContextFromRoot(simulator.get_context())
    np.testing.assert_allclose(marker.GetOutputPort("target_position").Eval(own), appli.TARGET)
    ok, text = apply(vocabulary.prepare(parse_command("gotoNd(taskRH, (0.45, -0.3, 0.9), '111', 5)")),
                     simulator.get_mutable_context())
    assert ok, text
    simulator.AdvanceTo(0.1)
    np.testing.assert_allclose(marker.GetOutputPort("target_position").Eval(own), [0.45, -0.3, 0.9])
    ok, text = apply(vocabulary.prepare(parse_command("signal(markerrh, 'target_position')")), simulator.get_context())
    assert ok and "0.45" in text, text
    # The controlled point is the tutorial's hand point (wrist + the seed's handMgrip (0.1, 0, 0)).
    np.testing.assert_allclose(marker.GetOutputPort("point_position").Eval(own),
                               handles.taskRH.current_pose(simulator.get_context()).translation(), atol=1e-12)


def test_the_summary_error_is_against_the_last_target():
    appli = talos_appli
    handles = appli.build_diagram(push_time=0.0)
    simulator = Simulator(handles.diagram)
    simulator.AdvanceTo(0.3)
    new = np.array([0.45, -0.3, 0.9])
    gotoNd(handles.taskRH, new, "111", 5.0, context=simulator.get_mutable_context())
    simulator.AdvanceTo(0.6)
    summary, trace = appli.summarize(handles, simulator, 0.6, 1.0)
    np.testing.assert_allclose(summary["target_m"], new)
    assert summary["hand_error_m"] == pytest.approx(np.linalg.norm(trace["hand_position"][-1] - new), rel=1e-12)
    assert summary["hand_error_m"] != pytest.approx(np.linalg.norm(trace["hand_position"][-1] - appli.TARGET), rel=1e-3)


# --- the README's first stack, on screen ---------------------------------------------------------


def target_coloured(png) -> np.ndarray:
    """The pixels of the target's colour (a saturated red, lit or not), as a boolean mask."""
    Image = pytest.importorskip("PIL.Image", reason="Pillow (matplotlib's dependency) reads the screenshot")
    rgb = np.asarray(Image.open(png).convert("RGB")).astype(int)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    assert (TARGET_COLOR.r(), TARGET_COLOR.g(), TARGET_COLOR.b()) == (1.0, 0.1, 0.05)  # what this mask is for
    return (r >= 180) & (r - g >= 150) & (r - b >= 150)


def serve(directory) -> http.server.ThreadingHTTPServer:
    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(directory)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


@pytest.mark.skipif(shutil.which("chromium") is None and shutil.which("chromium-browser") is None,
                    reason="headless Chromium is not installed (apt-get install chromium)")
def test_the_first_stack_target_is_on_screen_at_the_last_frame(tmp_path, monkeypatch):
    """The recording plays its 2 s once and stays on its last frame (the hand on the target): the
    screenshot is taken well after that (again later on a loaded host, see tests/chromium.py). The
    same recording without the marker has no such pixel."""
    from tests.chromium import screenshot_after, screenshot_until

    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__main__"}
    exec(compile(first_stack_code(), "README.md: Your first stack", "exec"), namespace)
    meshcat = namespace["meshcat"]
    meshcat.Delete("/target")
    (tmp_path / "without_marker.html").write_text(meshcat.StaticHtml())
    server = serve(tmp_path)
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}"
        shot, _ = screenshot_until(f"{url}/recording.html", tmp_path / "recording.png",
                                   lambda picture: target_coloured(picture).sum() >= 30, waits=(12.0, 40.0, 120.0))
        control = screenshot_after(f"{url}/without_marker.html", tmp_path / "without_marker.png", wait=12.0)
    finally:
        server.shutdown()
        server.server_close()
    assert target_coloured(control).sum() == 0, "the robot and the background have no pixel of the target's colour"
    assert target_coloured(shot).sum() >= 30, f"the target is not on screen: see {shot}"
