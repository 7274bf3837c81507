"""numba's first compilation, in two parts run side by side (``python -m tests.warm_up solvers|robot``).

``solvers``: random stacks through the hierarchical QP (its stages, equality-constrained steps and
active-set iterations). ``robot``: short runs of the tutorial under the hierarchical QP (features,
integration, limits, the curvature correction, the equality stacks' path) and of the dynamic stand
(the dynamic assembly and the QR path), and the collision rows' assembly and support gaps. See ``pytest_configure``
in tests/conftest.py.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np


def solvers() -> None:
    from sotdrake.hqp.solve import HierarchicalQP
    from tests.hqp_stacks import random_stack

    for seed in range(40):
        n, levels, x_lower, x_upper = random_stack(np.random.default_rng(seed))
        HierarchicalQP(n).solve(levels, x_lower, x_upper)


def robot() -> None:
    from sotdrake.collision import CollisionWorld, pair_distances
    from sotdrake.collision.schedule import PairSchedule, ScheduleState
    from sotdrake.robots import load_talos
    from sotdrake.scenarios import talos_appli, talos_dynamics

    world = CollisionWorld(load_talos("reduced"))
    context = world.new_context()
    pair_distances(world, context, 0.05, bias=True)
    schedule, q = PairSchedule(world), load_talos("reduced").half_sitting
    first = schedule.step(ScheduleState(), context, q, 0.05)  # (its gaps)
    schedule.step(first.state, context, q + 1e-3, 0.05)  # (its bounds after a motion)

    with tempfile.TemporaryDirectory() as out:
        quiet = ["--no-meshcat", "--quiet", "--duration", "0.01"]
        talos_appli.main(["--solver", "hqp", *quiet, "--out", str(Path(out) / "appli")])
        talos_dynamics.main(["--scenario", "stand", "--device", "dynsimu", *quiet, "--out", str(Path(out) / "dyn")])


if __name__ == "__main__":
    {"solvers": solvers, "robot": robot}[sys.argv[1]]()
