"""The basic SoT solver: a strict pseudo-inverse cascade (sot-core ``SOT``), as pure numpy.

For levels ``i = 1..n`` (``J_i v = ė_i*``), with ``Z_0 = I`` an orthonormal basis of ``R^nv``::

    A_i   = J_i Z_{i-1}                    (= J_i P_{i-1} restricted to the free directions)
    v_i   = v_{i-1} + Z_{i-1} A_i^♯ (ė_i* - J_i v_{i-1})
    Z_i   = Z_{i-1} · (right singular vectors of A_i beyond its numerical rank)

which is the seed's ``v_i = v_{i-1} + (J_i P_{i-1})^+ (ė_i* - J_i v_{i-1})`` with
``P_i = Z_i Z_iᵀ``. ``A^♯`` is built from the SVD ``A = U Σ Vᵀ``:

* singular values ``σ ≤ svd_threshold`` are truncated (the rank decision; sot-core's ``SOT``
  calls this threshold its "damping");
* ``damping = δ > 0`` gives the true damped inverse of the seed's slides,
  ``argmin ‖A x - r‖² + δ‖x‖²``, i.e. ``σ/(σ² + δ)`` on the kept directions. Damping trades a
  level's own accuracy for bounded velocities near singularities.

Lower levels only move in ``range(Z_i)``, on which ``J_i`` vanishes up to the truncated singular
values, so a lower level never changes a higher level's residual (strict priority).
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


class CascadeResult(NamedTuple):
    velocity: np.ndarray
    residuals: np.ndarray  # ‖J_i v - ė_i*‖ of each level, for the returned v
    ranks: np.ndarray  # numerical rank of each A_i


def solve_cascade(
    levels: Sequence[tuple[np.ndarray, np.ndarray]],
    nv: int,
    svd_threshold: float = 1e-4,
    damping: float | Sequence[float] = 0.0,
    control_selection: np.ndarray | None = None,
) -> CascadeResult:
    """Solve ``levels`` = ``[(J_1, ė_1*), …]`` in strict priority; see the module docstring.

    ``control_selection`` (nv booleans, sot-core's ``controlSelec``) restricts the solution to the
    selected velocity components (``Z_0`` = the selected columns of ``I``); the others are zero.
    ``damping`` is one δ for every level or one per level.

    Each level takes one LAPACK ``gesdd`` of ``A_iᵀ`` (``r × m``, Fortran-ordered as it comes, no
    copy): ``A_iᵀ = W Σ Uᵀ``, so ``W``'s columns are ``A_i``'s right singular vectors and its last
    ``r - rank`` columns the null space kept for the levels below. The last level takes the thin
    decomposition. A non-finite level raises :class:`~sotdrake.exceptions.SolverError`.
    """
    v = np.zeros(nv)
    Z = _identity(nv) if control_selection is None else _identity(nv)[:, control_selection]
    ranks = np.zeros(len(levels), dtype=int)
    last = len(levels) - 1
    dampings = [float(damping)] * len(levels) if np.ndim(damping) == 0 else list(damping)
    for i, (J, reference) in enumerate(levels):
        if Z.shape[1] == 0:
            continue
        A = J @ Z
        if A.shape[0] == 0:
            continue
        W, sigma, Ut, info = _gesdd(A.T, compute_uv=1, full_matrices=int(i < last))
        if info != 0:
            raise SolverError(f"level {i}: the SVD failed (LAPACK info {info}); is the level finite?")
        rank = int(np.count_nonzero(sigma > svd_threshold))
        ranks[i] = rank
        if rank:
            s = sigma[:rank]
            inverse = 1.0 / s if dampings[i] == 0.0 else s / (s * s + dampings[i])
            rhs = Ut[:rank] @ (reference - J @ v)
            v = v + Z @ (W[:, :rank] @ (inverse * rhs))
            if i < last:
                Z = Z @ W[:, rank:]
    residuals = np.array([math.sqrt(d @ d) for d in (J @ v - r for J, r in levels)])
    return CascadeResult(v, residuals, ranks)
