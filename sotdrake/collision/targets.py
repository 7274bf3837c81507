"""Random hand targets for the collision checks: inside the torso, across the body, inside or under
the table top (:data:`~.reach.TABLE`), in metres, world frame, TALOS in its reference posture."""

from __future__ import annotations

import numpy as np

#: Each family: the lower and upper corners of the box the targets are drawn in (m, world).
TARGET_BOXES: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "torso": ((-0.05, -0.12, 0.95), (0.10, 0.12, 1.25)),
    "across": ((0.10, 0.00, 0.80), (0.40, 0.40, 1.30)),
    "table": ((0.35, -0.55, 0.785), (0.75, 0.05, 0.815)),
    "under_table": ((0.35, -0.55, 0.60), (0.60, 0.05, 0.76)),
}


def random_targets(count: int, rng: np.random.Generator) -> list[tuple[str, np.ndarray]]:
    """``count`` targets, the families in turn, each uniform in its box."""
    families = list(TARGET_BOXES)
    out = []
    for i in range(count):
        family = families[i % len(families)]
        low, high = (np.array(corner) for corner in TARGET_BOXES[family])
        out.append((family, low + rng.random(3) * (high - low)))
    return out
