"""The docs site builds with warnings as errors, documents every public name, has no broken internal
link, opens in a browser, and its getting-started examples run as written; the README stays short
and written for users."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = ROOT / "README.md"
GETTING_STARTED = DOCS / "getting_started.md"
DOCUMENTED_SUBPACKAGES = ("features", "solvers", "hqp", "dynamics", "walking", "robots", "physics", "collision", "live", "sweep")


# --- the site ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site built as the README's Development section builds it, into a temporary folder."""
    for module in ("sphinx", "myst_parser", "furo"):
        pytest.importorskip(module, reason="the docs extra: pip install '.[docs]'")
    out = tmp_path_factory.mktemp("site")
    html, doctrees = out / "html", out / "doctrees"
    build = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html", "-d", str(doctrees), str(DOCS), str(html)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0, f"the docs build failed (warnings are errors):\n{build.stdout[-3000:]}\n{build.stderr[-6000:]}"
    return html


def public_names() -> dict[str, list[str]]:
    """``__all__`` of sotdrake and of its documented subpackages, imported from the checkout as the
    docs' conf.py does (the installed copy may be older)."""
    code = (
        "import json, sys, importlib; sys.path.insert(0, sys.argv[1]); import sotdrake; "
        "names = {'sotdrake': list(sotdrake.__all__)}; "
        "names.update({f'sotdrake.{m}': list(importlib.import_module(f'sotdrake.{m}').__all__) for m in sys.argv[2:]}); "
        "print(json.dumps(names))"
    )
    run = subprocess.run(
        [sys.executable, "-c", code, str(ROOT), *DOCUMENTED_SUBPACKAGES], capture_output=True, text=True, timeout=300, check=True
    )
    return json.loads(run.stdout.strip().splitlines()[-1])


def inventory(html: Path) -> set[str]:
    from sphinx.util.inventory import InventoryFile

    with open(html / "objects.inv", "rb") as stream:
        inv = InventoryFile.load(stream, "", lambda base, uri: uri)
    data = inv.data if hasattr(inv, "data") else inv
    return {name for objects in data.values() for name in objects}


def test_every_public_name_is_in_the_api_reference(site):
    names, documented = public_names(), inventory(site)
    top = names.pop("sotdrake")
    missing = [n for n in top if f"sotdrake.{n}" not in documented]
    assert not missing, f"names of sotdrake.__all__ missing from the API reference: {missing}"
    api_html = (site / "api" / "sotdrake.html").read_text()
    assert all(f'id="sotdrake.{n}"' in api_html for n in top)
    for page in (site / "api").glob("*.html"):  # the docstrings' literals render as written (none mangled)
        assert '<span class="pre">\\' not in page.read_text(), page.name
    for module, module_names in names.items():
        # a subpackage's page documents its own names; those it shares with the top level are there
        missing = [n for n in module_names if f"{module}.{n}" not in documented and n not in top]
        assert not missing, f"names of {module}.__all__ missing from the API reference: {missing}"


class _Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids: set[str] = set()
        self.links: list[str] = []

    def handle_starttag(self, tag, attrs):
        attributes = dict(attrs)
        if attributes.get("id"):
            self.ids.add(attributes["id"])
        if tag == "a" and attributes.get("name"):
            self.ids.add(attributes["name"])
        for key in ("href", "src"):
            if attributes.get(key) and tag in ("a", "img", "link", "script"):
                self.links.append(attributes[key])


def test_internal_links_resolve(site):
    pages: dict[Path, _Page] = {}
    for path in site.rglob("*.html"):
        page = _Page()
        page.feed(path.read_text(errors="replace"))
        pages[path.resolve()] = page
    broken = []
    for path, page in pages.items():
        for link in page.links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc or link.startswith(("mailto:", "javascript:", "data:")):
                continue  # external: not checked (no network in the tests)
            target = (path.parent / unquote(parts.path)).resolve() if parts.path else path
            if target.is_dir():
                target = target / "index.html"
            if not target.exists():
                broken.append(f"{path.relative_to(site)}: {link} (no such file)")
            elif parts.fragment and target.suffix == ".html" and target in pages and unquote(parts.fragment) not in pages[target].ids:
                broken.append(f"{path.relative_to(site)}: {link} (no such anchor)")
    assert not broken, "broken internal links:\n" + "\n".join(broken[:50])
    # the pages a newcomer needs are all there, with the pictures they reference
    for page in (
        "index",
        "getting_started",
        "tutorials/index",
        "concepts/index",
        "api/index",
        "benchmarks",
        "guide/your_robot",
        "changelog",
        "contributing",
    ):
        assert (site / f"{page}.html").exists(), page
    assert (site / "_images" / "talos_appli.png").exists()


def test_the_benchmark_tables_come_from_the_bench_json(site):
    generated = (DOCS / "_generated" / "benchmarks_tables.md").read_text()
    hostile = json.loads((ROOT / "bench" / "reference" / "hostile.json").read_text())
    assert f"Bad inputs tried: {hostile['bad_inputs']}" in generated
    page = (site / "benchmarks.html").read_text()
    assert page.count("<table") >= len(list((ROOT / "bench" / "reference").glob("*.json")))
    assert "bench/reference/dynamics.json" in page and "bench/reference.json" in page


# --- in a browser -------------------------------------------------------------------------------


def chromium_or_skip() -> str:
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    if path is None and Path("/usr/bin/chromium").exists():
        path = "/usr/bin/chromium"
    if path is None:
        pytest.skip("chromium not installed")
    return path


def dump_dom(chromium: str, page: Path, profile: Path) -> str:
    run = subprocess.run(
        [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--no-first-run",
            f"--user-data-dir={profile}",
            "--dump-dom",
            page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout


def visible_text(dom: str) -> str:
    body = dom.split("<body", 1)[1]
    body = re.sub(r"<(script|style|svg)\b.*?</\1>", " ", body, flags=re.S)
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", body)).strip()


def test_the_site_opens_in_headless_chromium(site, tmp_path):
    chromium = chromium_or_skip()
    index = dump_dom(chromium, site / "index.html", tmp_path / "profile-index")
    assert re.search(r"<title>[^<]*sotdrake[^<]*</title>", index)
    navigation = index.split('class="sidebar-tree"', 1)[1]  # furo's navigation
    for title in ("Getting started", "Tutorials", "Concepts", "API reference", "Benchmarks", "Changelog"):
        assert title in navigation, title
    assert "Stack of Tasks" in visible_text(index) and len(visible_text(index)) > 500

    api = dump_dom(chromium, site / "api" / "sotdrake.html", tmp_path / "profile-api")
    assert re.search(r"<title>[^<]*sotdrake[^<]*</title>", api)
    assert 'class="sidebar-tree"' in api and 'id="sotdrake.MetaTaskKine6d"' in api
    assert "gotoNd" in visible_text(api)


def test_the_front_page_renders_something_to_see(site, tmp_path):
    """A screenshot of the served site (tests/chromium.py's helper): not a blank page."""
    chromium_or_skip()
    import functools
    import http.server
    import threading

    import matplotlib.image

    from tests.chromium import screenshot_until

    def drawn(picture) -> bool:
        pixels = matplotlib.image.imread(picture)[..., :3]
        return bool(pixels.std() > 0.05 and (pixels.mean(axis=2) < 0.5).mean() > 0.01)  # dark text or pictures

    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(site))
    handler.log_message = lambda *args: None  # type: ignore[method-assign]
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        shot, shown = screenshot_until(f"http://127.0.0.1:{server.server_address[1]}/index.html", tmp_path / "index.png",
                                       drawn, waits=(2.0, 30.0))
    finally:
        server.shutdown()
        server.server_close()
    assert shown, f"the page looks blank: {shot}"


# --- the README -------------------------------------------------------------------------------

PROCESS_WORDS = re.compile(
    r"\bissue \d|\bissue's\b|\bthis round|next round|previous round|\bround of\b|load average|"
    r"\b[0-9a-f]{7,40}\b commit|\bcommit [0-9a-f]{7,40}\b|\b\d{1,2}:\d{2} (run|UTC)\b",
    re.I,
)


def test_the_readme_is_short_and_written_for_users():
    text = README.read_text()
    assert len(text.splitlines()) <= 250, f"README.md has {len(text.splitlines())} lines (at most 250): move the detail to docs/"
    found = PROCESS_WORDS.findall(text)
    assert not PROCESS_WORDS.search(text), f"README.md speaks of the work, not of the software: {found}"
    for section in (
        "## Install",
        "## Quick start",
        "## Your first stack",
        "## What is inside",
        "## Supported platforms",
        "## Tests",
        "## Development",
        "## Licence and citing",
        "## Links",
    ):
        assert f"\n{section}\n" in text, section
    # the two commands CI and the tests run, character for character
    demo = "python3 -m venv .venv && .venv/bin/pip install . && .venv/bin/python diagrams/talos_appli.py --duration 8 --out out/appli"
    tests = 'python3 -m venv .venv && .venv/bin/pip install ".[test]" && .venv/bin/python -m pytest -q'
    for command in (demo, tests):
        assert f"\n{command}\n" in text, command
    tests = text.split("\n## Tests\n", 1)[1].split("\n## ", 1)[0]
    assert '-m "not slow"' in tests and "min" in tests and ".ci/other-kernels" in tests  # measured, and how to skip
    development = text.split("\n## Development\n", 1)[1].split("\n## ", 1)[0]
    assert ".venv/bin/python -m sphinx -W --keep-going -b html docs docs/_build/html" in development
    assert "ruff check" in development and "mypy" in development
    assert "(diagrams/media/talos_appli.png)" in text and "BSD-3-Clause" in text


def test_the_readmes_relative_links_resolve():
    """The README's links to docs pages, CONTRIBUTING.md and pictures point at files of the checkout."""
    for path in (README, ROOT / "CHANGELOG.md", ROOT / "CONTRIBUTING.md"):
        for target in re.findall(r"\]\(([^)\s]+)\)", path.read_text()):
            if urlsplit(target).scheme or target.startswith("#"):
                continue
            assert (path.parent / urlsplit(target).path).exists(), f"{path.name}: {target}"


def shell_lines(path: Path) -> list[str]:
    blocks = re.findall(r"```(?:bash|sh|console)\n(.*?)```", path.read_text(), re.S)
    return [line.strip() for block in blocks for line in block.splitlines() if line.strip() and not line.strip().startswith("#")]


def test_shell_commands_run_from_a_fresh_clone():
    """No bare ``python``/``pip``/``sotdrake-shell`` that needs an activated environment; the scripts named exist."""
    for path in [README, ROOT / "CONTRIBUTING.md", *DOCS.rglob("*.md")]:
        if "_build" in path.parts or "_generated" in path.parts:
            continue
        for line in shell_lines(path):
            for command in re.split(r"&&|\|\||;", line.split("  #")[0]):
                words = command.split()
                if not words:
                    continue
                assert words[0] not in ("python", "pip", "pytest", "sotdrake-shell", "ruff", "mypy"), f"{path.name}: {line}"
                for script in re.findall(r"\b((?:diagrams|bench)/\w+\.py)\b", command):
                    assert (ROOT / script).exists(), f"{path.name}: {script}"


# --- the getting-started examples ------------------------------------------------------------


def section_code(path: Path, title: str) -> str:
    section = path.read_text().split(f"\n## {title}\n", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert len(blocks) == 1, f"{title}: the section holds one complete script"
    return blocks[0]


def run_example(title: str, tmp_path, monkeypatch) -> dict:
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__main__"}
    exec(compile(section_code(GETTING_STARTED, title), f"docs/getting_started.md: {title}", "exec"), namespace)
    return namespace


def test_the_first_stack_is_the_readmes():
    """The getting-started page's first stack is the README's, which tests/test_readme.py runs as written."""
    assert section_code(GETTING_STARTED, "Your first stack") == section_code(README, "Your first stack")


@pytest.mark.slow
def test_the_first_dynamic_stack_runs_as_written(tmp_path, monkeypatch, capsys):
    namespace = run_example("Your first dynamic stack", tmp_path, monkeypatch)
    robot, context = namespace["robot"], namespace["simulator"].get_context()
    assert context.get_time() == pytest.approx(1.0)
    com = robot.dynamic.GetOutputPort("com").Eval(robot.dynamic.GetMyContextFromRoot(context))
    assert np.linalg.norm(np.asarray(com) - robot.dynamic.com_at(robot.q0)) < 1e-3  # TALOS stands
    torque = namespace["torque"]
    assert np.all(np.isfinite(torque)) and np.abs(torque).max() > 1.0  # gravity is held by the torques
    out = capsys.readouterr().out
    assert "CoM drift after 1 s (m):" in out and "largest torque (N·m):" in out


@pytest.mark.slow
def test_the_first_walk_runs_as_written(tmp_path, monkeypatch, capsys):
    namespace = run_example("Your first walk", tmp_path, monkeypatch)
    context = namespace["simulator"].get_context()
    for foot in (namespace["right"], namespace["left"]):
        moved = foot.current_pose(context).translation() - foot.current_pose().translation()
        # two steps of 10 cm then the closing step: 0.2 m forward, on the ground (the feet's width is the gait's)
        assert moved[0] == pytest.approx(0.2, abs=2e-3) and abs(moved[1]) < 0.03 and abs(moved[2]) < 2e-3
    assert capsys.readouterr().out.count("sole advanced (m):") == 2
