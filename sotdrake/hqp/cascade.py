"""The basic SoT solver: a strict pseudo-inverse cascade (sot-core ``SOT``).

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
level's residual (strict priority). ``P_i`` is kept as an orthonormal basis ``Z_i`` of its range
(``P_i = P_0 Z_i Z_iᵀ``, ``P_0`` a mask on the Jacobians' columns): ``A_i = (J_i P_0 Z_{i-1}) Z_{i-1}ᵀ``,
so each level takes one SVD (LAPACK ``gesdd``) of the ``m × d_i`` matrix ``J_i P_0 Z_{i-1}``, whose
right singular vectors ``W`` give ``V_i = Z_{i-1} W_{≤rank}`` and ``Z_i = Z_{i-1} W_{>rank}``;
``d_i``, what is left free, shrinks down the stack (a posture level of nv rows at the bottom of a
stack is an ``nv × d`` SVD, not ``nv × nv``).

**Full-rank fast path** (no damping): stack the levels, ``B = [J_1; …; J_n] P_0`` (``M`` rows,
``M ≤ nv``), and take one Householder QR ``Bᵀ = Q R`` in priority order (no pivoting), so that
``B = L Qᵀ`` with ``L = Rᵀ`` lower triangular. While the higher levels are full rank,
``P_{i-1} = P_0 - Q_{<i} Q_{<i}ᵀ`` and ``A_i = J_i P_{i-1} = L_ii Q_iᵀ``: the singular values of
``A_i`` are those of the diagonal block ``L_ii``. If every block is certified above the
threshold, ``σ_min(L_ii) ≥ 1 / ‖L_ii⁻¹‖_F > svd_threshold``, the cascade keeps every direction,
solves every level exactly, and its ``v`` is the one point of ``range(Q)`` that does so:
``v = Q L⁻¹ r``. That is what this path returns (one QR, one triangular inverse; the blocks of
``R⁻¹`` on its diagonal are the ``R_ii⁻¹``). The QR of the first rows does not depend on the rows
below, so the path also solves the leading certified levels of any stack: when a block is not
certified (a rank loss, a conflict with a higher level, a singular value within ``√m_i`` of the
threshold, a NaN, or more rows than ``nv``), the SVD cascade above goes on from ``Z`` = the
other columns of ``Q`` (``P = P_0 - Q_K Q_Kᵀ``, ``Q_K``: the solved levels' columns) and decides.
The fast path and the SVD cascade below it are one compiled call (:mod:`.kernels.cascade`); the
plain :func:`svd_cascade` is their reference. References known before the solve (``extra``
of :func:`cascade_factorization`: ``SOT``'s curvature corrections, for its velocity limits) are
solved in the same compiled pass, as a second right-hand side.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from scipy.linalg.lapack import dgesdd as _gesdd

from ..compiled import compiled_input, kernels
from ..exceptions import MAX_COUNT, InvalidInput, SolverError, all_numbers, check_count
from .problem import floats


def _stacked(levels: Sequence[tuple[np.ndarray, np.ndarray]], extra: Sequence[np.ndarray] | None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(J, references, sizes)``: the levels' rows stacked (M × nv), their references as one column
    (M × 1) and the ``extra`` ones as a second, and each level's number of rows."""
    sizes = np.array([J.shape[0] for J, _ in levels], dtype=np.int64)
    if extra is not None and len(extra) != len(levels):
        raise InvalidInput(f"extra: one reference per level ({len(levels)}), got {len(extra)}")
    for k, (size, (_, r)) in enumerate(zip(sizes.tolist(), levels, strict=True)):
        if np.shape(r) != (size,) or (extra is not None and np.shape(extra[k]) != (size,)):
            raise InvalidInput(f"level {k}: {size} rows and references of shape {np.shape(r)}"
                               + ("" if extra is None else f" and {np.shape(extra[k])}"))
    J = levels[0][0] if len(levels) == 1 else np.concatenate([J for J, _ in levels])
    references = np.empty((J.shape[0], 1 if extra is None else 2))
    references[:, 0] = levels[0][1] if len(levels) == 1 else np.concatenate([r for _, r in levels])
    if extra is not None:
        references[:, 1] = np.concatenate(extra)
    return J, references, sizes


def _selection_mask(control_selection: Any, nv: int) -> np.ndarray:
    """``control_selection`` (nv booleans, or 0 and 1) as a float mask, or :class:`InvalidInput`."""
    try:
        given = np.asarray(control_selection)
    except (TypeError, ValueError):  # (a ragged list)
        given = np.zeros(0, dtype=object)
    if given.dtype.kind not in "biuf":  # (strings, complex numbers, None)
        raise InvalidInput(f"control_selection: nv booleans (or 0 and 1), one per velocity, got {control_selection!r:.80}")
    if given.shape != (nv,):
        raise InvalidInput(f"control_selection: {nv} values expected, got shape {given.shape}")
    mask = given.astype(float)
    if given.dtype != bool and not ((mask == 0.0) | (mask == 1.0)).all():
        raise InvalidInput("control_selection: nv booleans (or 0 and 1), one per velocity")
    return mask


def _real_levels(levels: Any) -> list[tuple[np.ndarray, np.ndarray]]:
    """``levels`` as ``(J, ė*)`` pairs of float arrays (lists converted), or :class:`InvalidInput`
    naming the level: not a pair, not real numbers, J not a matrix, a NaN or an infinite entry."""
    if isinstance(levels, (str, bytes)) or not isinstance(levels, Sequence):
        raise InvalidInput(f"levels: a sequence of (J, ė*) pairs, highest priority first, got {levels!r:.80}")
    pairs, bad = [], []
    for k, level in enumerate(levels):
        if not isinstance(level, (tuple, list)) or len(level) != 2:
            raise InvalidInput(f"levels[{k}]: a (J, ė*) pair of arrays, got {level!r:.80}")
        J, r = floats(f"levels[{k}]: J", level[0]), floats(f"levels[{k}]: ė*", level[1])
        if J.ndim != 2:
            raise InvalidInput(f"levels[{k}]: J must be a matrix (2-D), got shape {J.shape}")
        if not (np.isfinite(J).all() and np.isfinite(r).all()):
            bad.append(k)
        pairs.append((J, r))
    if bad:
        raise InvalidInput(f"levels {bad}: Jacobians and references must be finite")
    return pairs


_kernels = kernels(".kernels.cascade", __package__, "cascade", "the basic SoT's cascade", "a few seconds")


class CascadeResult(NamedTuple):
    velocity: np.ndarray
    residuals: np.ndarray | None  # ‖J_i v - ė_i*‖ of each level, for the returned v
    ranks: np.ndarray  # numerical rank of each A_i


class CascadeFactorization(NamedTuple):
    """The cascade of a stack solved for its references (``velocity``, and each level's rank) and,
    when it was given extra references, for those (``extra_velocity``, else None)."""

    velocity: np.ndarray
    ranks: np.ndarray
    extra_velocity: np.ndarray | None = None


def cascade_factorization(
    levels: Sequence[tuple[np.ndarray, np.ndarray]],
    nv: int,
    svd_threshold: float = 1e-4,
    damping: float | Sequence[float] = 0.0,
    control_selection: np.ndarray | None = None,
    extra: Sequence[np.ndarray] | None = None,
) -> CascadeFactorization:
    """:func:`solve_cascade`'s solve (:class:`CascadeFactorization`).
    ``extra`` (one per level, the sizes of the references): other references solved in the same
    pass, their ``v`` kept as ``extra_velocity`` (by linearity, any combination of the two
    references is then the same combination of the two velocities)."""
    # (The checks of a solver's every tick take the first branch of each: a Python float, a bool mask.)
    if (type(damping) is float or type(damping) is int) and 0 <= damping < math.inf:
        dampings = np.zeros(len(levels)) if damping == 0 else np.full(len(levels), float(damping))
    elif all_numbers(damping):
        dampings = np.array(damping, dtype=float)
        dampings = np.full(len(levels), float(dampings)) if dampings.ndim == 0 else dampings
        if not (dampings >= 0).all() or not np.isfinite(dampings).all():
            raise InvalidInput(f"damping: finite numbers ≥ 0, got {dampings}")
    else:
        raise InvalidInput(f"damping: one number or one per level, got {damping!r:.80}")
    if dampings.shape != (len(levels),):
        raise InvalidInput(f"damping: one value or one per level ({len(levels)}), got {dampings.size}")
    if not (type(svd_threshold) is float and 0 <= svd_threshold < math.inf) and not (
            all_numbers(svd_threshold) and np.ndim(svd_threshold) == 0 and 0 <= svd_threshold < np.inf):
        raise InvalidInput(f"svd_threshold: a finite number ≥ 0, got {svd_threshold!r:.80}")
    if not (type(nv) is int and 0 <= nv <= MAX_COUNT):
        nv = check_count("nv (the number of velocities)", nv, 0)
    mask = np.ones(nv) if control_selection is None else _selection_mask(control_selection, nv)
    if not levels:
        return CascadeFactorization(np.zeros(nv), np.zeros(0, dtype=int), None if extra is None else np.zeros(nv))
    J, references, sizes = _stacked(levels, extra)
    if J.ndim != 2 or J.shape[1] != nv:
        raise InvalidInput(f"the levels' Jacobians: {nv} columns expected, got shape {J.shape}")
    try:
        v, ranks, _ = _kernels().cascade(compiled_input(J), sizes, references, mask, float(svd_threshold), dampings)
    except np.linalg.LinAlgError as error:
        raise SolverError(f"the SVD cascade failed ({error}); is every level finite?") from error
    return CascadeFactorization(np.ascontiguousarray(v[:, 0]), ranks, None if extra is None else np.ascontiguousarray(v[:, 1]))


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
    selected velocity components (``P_0 = diag(selection)``); the others are zero. ``nv``: an integer
    in [0, :data:`~sotdrake.exceptions.MAX_COUNT`]; the arrays may be (nested) lists of real numbers.
    ``damping`` is one δ for every level or one per level. ``with_residuals=False`` leaves
    ``residuals`` None (see :func:`cascade_residuals`).

    Without damping, the full-rank fast path first (see the module docstring); otherwise, or when
    it cannot certify every level, :func:`svd_cascade`: one LAPACK ``gesdd`` of ``A_iᵀ`` per level
    (Fortran-ordered as it comes, no copy): ``A_iᵀ = W Σ Uᵀ``, so ``W``'s columns are ``A_i``'s
    right singular vectors. A LAPACK failure raises :class:`~sotdrake.exceptions.SolverError`.
    """
    levels = _real_levels(levels)
    solved = cascade_factorization(levels, nv, svd_threshold, damping, control_selection)
    v = solved.velocity
    return CascadeResult(v, cascade_residuals(levels, v) if with_residuals else None, solved.ranks)


def svd_cascade(levels: Sequence[tuple[np.ndarray, np.ndarray]], nv: int, svd_threshold: float,
                dampings: Sequence[float], control_selection: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """``(v, ranks)`` of the cascade, one SVD per level (the compiled path's reference); ``dampings``:
    one δ per level."""
    v = np.zeros(nv)
    mask = None if control_selection is None else np.asarray(control_selection, dtype=bool)
    Z = None  # an orthonormal basis of what the levels above leave free (None: every direction)
    ranks = np.zeros(len(levels), dtype=int)
    last = len(levels) - 1
    for i in range(len(levels)):
        J, reference = levels[i]
        if J.shape[0] == 0 or (Z is not None and Z.shape[1] == 0):  # nothing asked, or nothing left free
            continue
        # A_i = J P_0 P_{i-1} with P_{i-1} = Z Zᵀ: the SVD of J P_0 Z (m × d), whose right singular
        # vectors W map back by Z; (J P_0 Z)ᵀ = W Σ Uᵀ. Below the last level W comes in full: its
        # columns past the rank span what is left free.
        A = J if mask is None else J * mask
        if Z is not None:
            A = A @ Z
        W, sigma, Ut, info = _gesdd(A.T, compute_uv=1, full_matrices=int(i < last))
        if info != 0:
            raise SolverError(f"level {i}: the SVD failed (LAPACK info {info}); is the level finite?")
        rank = sum(1 for x in sigma.tolist() if x > svd_threshold)
        ranks[i] = rank
        if rank:
            s = sigma[:rank]
            inverse = 1.0 / s if dampings[i] == 0.0 else s / (s * s + dampings[i])
            V = W[:, :rank] if Z is None else Z @ W[:, :rank]
            Ut = Ut[:rank]
            v = v + V @ (inverse * (Ut @ (reference - J @ v if i else reference)))
        if i < last:
            Z = W[:, rank:] if Z is None else Z @ W[:, rank:]
    return v, ranks


def cascade_residuals(levels: Sequence[tuple[np.ndarray, np.ndarray]], v: np.ndarray) -> np.ndarray:
    """``‖J_i v - ė_i*‖`` of each level."""
    return np.array([math.sqrt(d @ d) for d in (J @ v - r for J, r in levels)])
