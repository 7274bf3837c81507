#!/usr/bin/env python3
"""Regenerate the README's pictures from the scripts themselves, so they stay current.

* ``talos_appli.png``: TALOS at the END of the tutorial (8 s), from a camera that looks at the right
  hand on the red target. The tutorial's diagram is run; its Meshcat scene then holds the last pose,
  saved as a static page and screenshot by headless Chromium (Debian package ``chromium``).
* ``talos_appli_control_graph.svg``: the tutorial's control graph (:func:`write_control_graph`).
* ``talos_appli_plots.png``: the tutorial's plots; ``talos_physics_plots.png``: the physics ``reach``
  scenario's plots (``--no-physics`` skips that 8 s physical simulation).

The hero image needs Meshcat and Chromium, so this script has no ``--no-meshcat``; ``--out`` and
``--duration`` are checked (and Chromium looked for) before anything runs.

    python diagrams/make_readme_media.py --out diagrams/media
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from sotdrake import run_script, script_arguments, simulate, start, start_meshcat, write_control_graph
from sotdrake.scenarios import talos_appli, talos_physics

#: The hero camera: in front of TALOS, a little to its left and above, so that the right hand on
#: the target is seen against the torso (from the right side, the reaching arm hides it).
HERO_CAMERA = {"camera_in_world": [1.75, 0.45, 1.4], "target_in_world": [0.3, -0.12, 0.72]}
HERO_SIZE = (1200, 800)
NO_CHROMIUM = "the hero image needs Chromium (e.g. `apt-get install chromium`)"


def chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path is not None:
            return path
    return None


def screenshot(html: Path, png: Path, size: tuple[int, int] = HERO_SIZE, crop_top: int = 24) -> Path:
    """A PNG of ``html`` by headless Chromium (software WebGL), without Meshcat's control bar."""
    import matplotlib.image

    browser = chromium()
    if browser is None:
        raise SystemExit(NO_CHROMIUM)
    raw = png.with_suffix(".raw.png")
    subprocess.run([browser, "--headless", "--enable-unsafe-swiftshader", "--no-sandbox", "--hide-scrollbars",
                    f"--window-size={size[0]},{size[1]}", "--timeout=20000", f"--screenshot={raw}",
                    html.resolve().as_uri()], check=True, capture_output=True)
    image = matplotlib.image.imread(raw)
    matplotlib.image.imsave(png, image[crop_top:])
    raw.unlink()
    return png


def hero(out: Path, duration: float = 8.0, progress: bool = True) -> dict:
    """Run the tutorial with Meshcat drawing; then photograph its last pose."""
    meshcat = start_meshcat()
    appli = talos_appli.build_diagram(meshcat)
    simulator, wall = simulate(appli.diagram, duration, visualizer=None, progress=progress, label="tutorial")
    appli.diagram.ForcedPublish(simulator.get_context())  # the scene shows the final pose
    meshcat.SetCameraPose(**HERO_CAMERA)
    summary, trace = talos_appli.summarize(appli, simulator, duration, wall)
    with tempfile.TemporaryDirectory() as tmp:
        page = Path(tmp) / "final.html"
        page.write_text(meshcat.StaticHtml())
        screenshot(page, out / "talos_appli.png")
    write_control_graph(appli.diagram, out / "talos_appli_control_graph.svg")
    (out / "talos_appli_control_graph.dot").unlink(missing_ok=True)
    talos_appli.plot(trace, appli.target, out / "talos_appli_plots.png")
    return summary


def physics_plots(out: Path, duration: float = 8.0, progress: bool = True) -> dict:
    run = talos_physics.build_diagram("reach")
    simulator, wall = simulate(run.diagram, duration, progress=progress, label="physics reach")
    summary, trace = talos_physics.summarize(run, simulator, duration, wall)
    talos_physics.plot(trace, out / "talos_physics_plots.png", "talos_physics: reach, open loop")
    return summary


def main(argv: list[str] | None = None) -> None:
    parser = script_arguments(__doc__, "diagrams/media", bag=False, meshcat=False)  # (the hero image needs Meshcat)
    parser.add_argument("--no-physics", action="store_true", help="leave talos_physics_plots.png as it is")
    args = parser.parse_args(argv)
    start(args)  # (--duration and --out checked, --out made: "error: --out …", exit status 2)
    if chromium() is None:
        raise SystemExit(NO_CHROMIUM)
    summary = hero(args.out, args.duration, not args.quiet)
    print(f"tutorial at t = {args.duration:g} s: hand {summary['hand_error_m']:.1e} m from the target; "
          f"wrote talos_appli.png, talos_appli_control_graph.svg, talos_appli_plots.png in {args.out}")
    nodes = (args.out / "talos_appli_control_graph.svg").read_text().count('class="node"')
    print(f"control graph: {nodes} nodes")
    if not args.no_physics:
        physics = physics_plots(args.out, args.duration, not args.quiet)
        print(f"physics reach: hand {1e3 * physics['hand_error_m']:.1f} mm from the target; "
              "wrote talos_physics_plots.png")


if __name__ == "__main__":
    run_script(main)
