import os
import subprocess
import sys
from pathlib import Path

# One BLAS thread per test process, set before numpy loads OpenBLAS (numpy's and scipy's read it
# then): the suite runs a process per core, and a second BLAS thread in each made the dynamic
# tests about 25 % slower in CPU (the solvers' matrices are small; the threads only contend).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pytest
from numba import config as numba_config

from sotdrake.robots import load_talos

#: The longest test files (most wall time first), started before the others. The suite is spread
#: over the cores file by file (pyproject.toml's addopts: ``--dist loadfile --no-loadscope-reorder``,
#: files handed out in collection order); started last, a long file would leave one worker running
#: it alone at the end. A file missing here only costs balance.
LONGEST_FIRST = (
    "test_live_run.py", "test_collision.py", "test_docs.py", "test_walking_physics.py", "test_solver_kine.py", "test_physics.py",
    "test_toolbox.py", "test_walking_multibody_zmp.py", "test_sweep.py", "test_hqp.py", "test_sweep_maps.py",
    "test_types.py", "test_talos_appli.py", "test_mistakes.py", "test_hostile.py", "test_dynamics.py",
)


#: A test of the compiled code itself (its signatures, its compilations): skipped when the package
#: runs as plain Python (``NUMBA_DISABLE_JIT=1``, one of CI's other-kernel runs).
compiled_only = pytest.mark.skipif(bool(numba_config.DISABLE_JIT), reason="checks the compiled code (NUMBA_DISABLE_JIT=1)")


def _compiled_cache_is_cold() -> bool:
    """Whether numba has no cache of the active-set iterations yet (a new install, or a new cache folder)."""
    import sotdrake.hqp.kernels.active_set as kernel

    where = Path(os.environ["NUMBA_CACHE_DIR"]) if os.environ.get("NUMBA_CACHE_DIR") else Path(kernel.__file__).parent
    return not where.is_dir() or next(where.rglob(f"{Path(kernel.__file__).stem}.solve-*.nbi"), None) is None


def pytest_configure(config):
    """After a new install, numba's first compilation (about two minutes of CPU) would happen in
    every test process that reaches a kernel before another has cached it. Here it happens once, in
    two processes side by side (tests/warm_up.py), before the workers start; if a warm-up run fails,
    the tests compile as they go. Not in a pytest-xdist worker, nor with the JIT disabled."""
    if hasattr(config, "workerinput") or numba_config.DISABLE_JIT or not _compiled_cache_is_cold():
        return
    root = Path(__file__).resolve().parents[1]
    print("compiling the numba kernels once, in two processes (after a new install) …", file=sys.stderr, flush=True)
    env = dict(os.environ, PYTHONPATH=str(root))
    runs = [subprocess.Popen([sys.executable, "-m", "tests.warm_up", part], cwd=root, env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL) for part in ("solvers", "robot")]
    for run in runs:
        run.wait()


def pytest_collection_modifyitems(config, items):
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: the order within a file is kept


@pytest.fixture(scope="session")
def talos_model():
    return load_talos("reduced")


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)


def random_configuration(model, rng, spread: float = 0.5) -> np.ndarray:
    """Half-sitting moved by a random velocity: joints within their limits, any base pose."""
    from sotdrake.configuration import Layout, integrate

    q = integrate(model.half_sitting, rng.normal(scale=spread, size=model.nv), 1.0, Layout.of(model.plant))
    lo, up = model.plant.GetPositionLowerLimits(), model.plant.GetPositionUpperLimits()
    return np.clip(q, lo, up)
