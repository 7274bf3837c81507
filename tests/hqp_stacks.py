"""Random hierarchical stacks for the HQP tests and benchmarks (one generator, shared).

Each stack: ``n`` in [5, 40] variables, 1-5 levels of 1-10 rows; rank-deficient levels; rows copied
from a higher level (or combinations of its rows) with other targets (conflicts); inequality rows,
some with a ±∞ side; rows scaled by 10^U(-3, 3); fixed variables; bounds loose, tight or mixed.
"""

from __future__ import annotations

import numpy as np

from sotdrake.hqp.solve import LevelRows


def random_stack(rng: np.random.Generator, n_range=(5, 40), max_levels: int = 5, scaled: bool = True):
    """``(n, levels, x_lower, x_upper)``, see the module docstring (``scaled=False``: no row scaling,
    for comparisons with references that are only well conditioned on unit-scale rows)."""
    n = int(rng.integers(n_range[0], n_range[1] + 1))
    levels = []
    for _ in range(int(rng.integers(1, max_levels + 1))):
        m = int(rng.integers(1, 11))
        rank = int(rng.integers(1, min(m, n) + 1))
        A = rng.normal(size=(m, rank)) @ rng.normal(size=(rank, n)) / np.sqrt(rank)
        if levels and rng.random() < 0.4:  # conflicts: rows of a higher level, or combinations of them
            above = levels[int(rng.integers(len(levels)))].A
            copies = int(rng.integers(1, m + 1))
            A[:copies] = rng.normal(size=(copies, len(above))) @ above if rng.random() < 0.5 else \
                above[rng.integers(len(above), size=copies)]
        scale = 10.0 ** rng.uniform(-3, 3, size=(m, 1))
        A *= scale if scaled and rng.random() < 0.5 else 1.0
        b = (A @ rng.normal(size=n)) * rng.uniform(0.1, 2.0)
        inequality = rng.random(m) < rng.choice([0.0, 0.5, 1.0])
        width = np.abs(b) * rng.uniform(0.0, 1.0, m) + 1e-3 * np.linalg.norm(A, axis=1)
        lower = np.where(inequality, b - width, b)
        upper = np.where(inequality, b + width, b)
        lower[inequality & (rng.random(m) < 0.25)] = -np.inf
        upper[inequality & (rng.random(m) < 0.25)] = np.inf
        levels.append(LevelRows(A, lower, upper))
    kind = rng.choice(["loose", "tight", "mixed", "none"])
    size = {"loose": rng.uniform(1.0, 10.0, n), "tight": rng.uniform(0.01, 0.3, n),
            "mixed": 10.0 ** rng.uniform(-2, 1, n), "none": np.full(n, np.inf)}[kind]
    x_upper = np.where(rng.random(n) < 0.8, size, np.inf)
    x_lower = np.where(rng.random(n) < 0.8, -size * rng.uniform(0.2, 1.0, n), -np.inf)
    fixed = rng.random(n) < 0.1
    x_lower[fixed] = x_upper[fixed] = rng.uniform(-0.1, 0.1, int(fixed.sum()))
    return n, levels, x_lower, x_upper
