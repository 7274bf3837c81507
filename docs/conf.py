"""Sphinx configuration of the sotdrake docs site.

Build (warnings are errors)::

    .venv/bin/python -m sphinx -W --keep-going -b html docs docs/_build/html
"""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))
sys.path.insert(0, str(ROOT))

project = "sotdrake"
author = "the sotdrake developers"
copyright = "the sotdrake developers, BSD-3-Clause"
try:
    from importlib.metadata import version as _version

    release = _version("sotdrake")
except Exception:  # not installed: the docs still build from the checkout
    release = "0.1.0"
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.autosummary",  # the names of each API page at a glance (no generated stub pages)
    "sphinx.ext.mathjax",
    "sotdrake_docs",  # docs/_ext: the benchmark tables from bench JSON, written at build time
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "_generated", "Thumbs.db", ".DS_Store"]
myst_enable_extensions = ["colon_fence", "dollarmath", "deflist"]
myst_heading_anchors = 3

html_theme = "furo"
html_title = f"sotdrake {release}"
html_static_path: list[str] = []

# autodoc: a module's members are the names of its __all__, in that order.
autodoc_default_options = {
    "members": True,
    "undoc-members": True,
    "member-order": "bysource",
    "show-inheritance": False,
}
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autodoc_inherit_docstrings = True
# sotdrake.ros (the ros2 extra) is documented with ROS mocked: the site builds with or without it.
autodoc_mock_imports: list[str] = ["rclpy", "std_msgs", "sensor_msgs", "std_srvs", "geometry_msgs",
                                   "builtin_interfaces", "trajectory_msgs", "rosbags"]
autosummary_generate = False
napoleon_google_docstring = True
napoleon_numpy_docstring = True

# No warning class is suppressed: the few docstrings that are not clean reST are mended at build time
# by docs/_ext/sotdrake_docs.py (fix_docstring), without changing what they say.
nitpicky = False
