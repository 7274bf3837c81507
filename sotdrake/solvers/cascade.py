"""The basic SoT solver: a strict pseudo-inverse cascade (sot-core ``SOT``), as pure numpy.

For levels ``i = 1..n`` (``J_i v = ė_i*``), with ``P_0 = I`` (or the projector on the selected
velocities, see ``control_selection``)::

    A_i   = J_i P_{i-1}                    (J_i restricted to what the higher levels leave free)
    v_i   = v_{i-1} + A_i^♯ (ė_i* - J_i v_{i-1})
    P_i   = P_{i-1} - V_i V_iᵀ             (V_i: the kept right singular vectors of A_i)

which is the seed's ``v_i = v_{i-1} + (J_i P_{i-1})^+ (ė_i* - J_i v_{i-1})``. ``A^♯`` is built from
the thin SVD ``A = U Σ Vᵀ``:

* singular values ``σ ≤ svd_threshold`` are truncated (the rank decision; sot-core's ``SOT``
  calls this threshold its "damping");
* ``damping = δ > 0`` gives the true damped inverse of the seed's slides,
  ``argmin ‖A x - r‖² + δ‖x‖²``, i.e. ``σ/(σ² + δ)`` on the kept directions. Damping trades a
  level's own accuracy for bounded velocities near singularities.

The right singular vectors of ``J_i P_{i-1}`` lie in ``range(P_{i-1})``, so ``P_i`` stays the
orthogonal projector on the null space of every level so far (up to the truncated singular
values), lower levels only move in ``range(P_i)``, and a lower level never changes a higher
level's residual (strict priority). One thin SVD per level (LAPACK ``gesdd`` of the ``nv × m``
matrix ``A_iᵀ``, no full ``nv × nv`` basis) and two ``nv × nv`` products.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache
from typing import NamedTuple

import numpy as np
from scipy.linalg.lapack import dgesdd as _gesdd

from ..exceptions import SolverError


@lru_cache(maxsize=8)
def _identity(n: int) -> np.ndarray:
    identity = np.eye(n)
    identity.flags.writeable = False
    return identity


@lru_cache(maxsize=8)
def _projector(selection: bytes) -> np.ndarray:
    """The projector on the selected velocities (``diag(selection)``), read-only and cached."""
    P = np.diag(np.frombuffer(selection, dtype=bool).astype(float))
    P.flags.writeable = False
    return P


class CascadeResult(NamedTuple):
    velocity: np.ndarray
    residuals: np.ndarray | None  # ‖J_i v - ė_i*‖ of each level, for the returned v
    ranks: np.ndarray  # numerical rank of each A_i


def solve_cascade(
    levels: Sequence[tuple[np.ndarray, np.ndarray]],
    nv: int,
    svd_threshold: float = 1e-4,
    damping: float | Sequence[float] = 0.0,
    control_selection: np.ndarray | None = None,
    with_residuals: bool = True,
) -> CascadeResult:
    """Solve ``levels`` = ``[(J_1, ė_1*), …]`` in strict priority; see the module docstring.

    ``control_selection`` (nv booleans, sot-core's ``controlSelec``) restricts the solution to the
    selected velocity components (``P_0 = diag(selection)``); the others are zero.
    ``damping`` is one δ for every level or one per level. ``with_residuals=False`` leaves
    ``residuals`` None (see :func:`cascade_residuals`).

    Each level takes one LAPACK ``gesdd`` of ``A_iᵀ`` (Fortran-ordered as it comes, no copy):
    ``A_iᵀ = W Σ Uᵀ``, so ``W``'s columns are ``A_i``'s right singular vectors. A LAPACK failure
    raises :class:`~sotdrake.exceptions.SolverError`.
    """
    v = np.zeros(nv)
    P = _identity(nv) if control_selection is None else _projector(np.asarray(control_selection, dtype=bool).tobytes())
    ranks = np.zeros(len(levels), dtype=int)
    last = len(levels) - 1
    dampings = [float(damping)] * len(levels) if isinstance(damping, (int, float)) else list(damping)
    for i, (J, reference) in enumerate(levels):
        if J.shape[0] == 0:
            continue
        A = J @ P
        W, sigma, Ut, info = _gesdd(A.T, compute_uv=1, full_matrices=0)
        if info != 0:
            raise SolverError(f"level {i}: the SVD failed (LAPACK info {info}); is the level finite?")
        rank = sum(1 for x in sigma.tolist() if x > svd_threshold)
        ranks[i] = rank
        if rank:
            s = sigma[:rank]
            inverse = 1.0 / s if dampings[i] == 0.0 else s / (s * s + dampings[i])
            V = W[:, :rank]
            rhs = Ut[:rank] @ (reference - J @ v if i else reference)
            v = v + V @ (inverse * rhs)
            if i < last:
                P = P - V @ V.T
    return CascadeResult(v, cascade_residuals(levels, v) if with_residuals else None, ranks)


def cascade_residuals(levels: Sequence[tuple[np.ndarray, np.ndarray]], v: np.ndarray) -> np.ndarray:
    """``‖J_i v - ė_i*‖`` of each level."""
    return np.array([math.sqrt(d @ d) for d in (J @ v - r for J, r in levels)])
