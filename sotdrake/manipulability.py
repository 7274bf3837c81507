"""Yoshikawa's manipulability of a frame's Jacobian, and its gradient from the Jacobian's derivative.

For the rows ``J`` (k×nv, k ≤ nv) of a frame F's Jacobian ``J_WF`` (rows ``(ω_WF; v_WF)``, world,
``v_WF`` the velocity of F's origin), the manipulability is ``μ = √det(J Jᵀ)``: the volume of the
velocity ellipsoid, zero at a singularity. Its rate along a motion ``v`` is
``μ̇ = μ · tr((J Jᵀ)⁻¹ J̇ Jᵀ) = g·v``, with, for each velocity direction ``e_k``,
``g_k = μ · ⟨J⁺ᵀ, ∂J[e_k]⟩`` (``J⁺ᵀ = (J Jᵀ)⁻¹ J``, ``⟨·,·⟩`` the entrywise product summed).

``∂J[e_k]``, the derivative of the Jacobian when the robot moves along ``e_k``, comes from the
Jacobian itself. With ``p_F`` the position of F, the columns of the spatial Jacobian
``Jˢ = (J_ω; J_v + [p_F]× J_ω)`` are the twists ``S_i`` of the velocity coordinates (about the world
origin), and moving along ``e_k`` changes ``S_i`` by the Lie bracket ``ad(S_k) S_i =
(ω_k × ω_i; ω_k × v_i + v_k × ω_i)`` when coordinate k moves coordinate i's axis (k upstream of i:
``upstream[k, i]``), else not at all. Then ``∂J_ω = ∂Jˢ_ω`` and
``∂J_v = ∂Jˢ_v − [∂p_F]× J_ω − [p_F]× ∂Jˢ_ω`` with ``∂p_F = J_v e_k``.

``upstream`` comes from the plant (:func:`upstream_coordinates`): a joint's coordinates move those
of the joints below it; a floating base's translations move its rotations' twists (they turn about
the base's origin) and, with its rotations, every joint's; the base's rotations (world axes) do not
move each other's twists. Inside a planar joint its translations move its rotation's axis, inside a
universal joint its first angle turns its second axis.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_triangular

from .exceptions import InvalidInput, check_finite


def _cross_columns(a: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``a × B[:, j]`` for every column j (a: 3, B: 3×n)."""
    return np.cross(a[:, None], B, axis=0)


def jacobian_derivatives(J_WF: np.ndarray, p_WF: np.ndarray, upstream: np.ndarray) -> np.ndarray:
    """``∂J[e_k]`` for every k: an array (nv, 6, nv), ``[k]`` the derivative of ``J_WF`` along ``e_k``
    (see the module docstring)."""
    J_w, J_v = J_WF[:3], J_WF[3:]
    p = np.asarray(p_WF, dtype=float)
    S_w, S_v = J_w, J_v + _cross_columns(p, J_w)  # the spatial Jacobian's columns (twists about the origin)
    nv = J_WF.shape[1]
    out = np.zeros((nv, 6, nv))
    moving = np.abs(J_WF).sum(axis=0) > 0  # the coordinates that move F (the others' columns are zero)
    for k in np.flatnonzero(moving):
        below = upstream[k] & moving
        dS_w, dS_v = np.zeros((3, nv)), np.zeros((3, nv))
        dS_w[:, below] = _cross_columns(S_w[:, k], S_w[:, below])
        dS_v[:, below] = _cross_columns(S_w[:, k], S_v[:, below]) + _cross_columns(S_v[:, k], S_w[:, below])
        out[k, :3] = dS_w
        out[k, 3:] = dS_v - _cross_columns(J_v[:, k], J_w) - _cross_columns(p, dS_w)  # ∂p_F = J_v e_k
    return out


def manipulability(J: np.ndarray) -> float:
    """``μ = √det(J Jᵀ)`` of the rows ``J`` (k×nv, k ≤ nv); 0 at a singularity. Computed as
    ``|det R|`` of the QR factorisation ``Jᵀ = Q R`` (the product of ``J``'s singular values), not
    from ``det(J Jᵀ)``, whose round-off squares ``J``'s condition number (μ = 1e-8 read as 2e-8);
    a diagonal entry of ``R`` within :data:`SINGULAR` of ``‖J‖`` (round-off) is a singularity.
    ``J``: an array or nested lists of finite numbers; NaN or infinity (which used to read as a
    singularity, μ = 0) is an :class:`InvalidInput`."""
    return _factors(check_finite("manipulability: J", J))[0]


#: A diagonal entry of ``R`` (``Jᵀ = Q R``) at most this fraction of ``‖J‖_F`` is round-off: μ = 0.
SINGULAR = 1e-14


def _factors(J: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """``(μ, Q, R)`` with ``Jᵀ = Q R`` (reduced)."""
    if J.ndim != 2 or J.shape[0] > J.shape[1] or J.shape[0] == 0:
        raise InvalidInput(f"manipulability: J must have between 1 and nv rows, got shape {J.shape}")
    Q, R = np.linalg.qr(J.T)
    diagonal = np.abs(np.diag(R))
    if not diagonal.min() > SINGULAR * np.linalg.norm(J):
        return 0.0, Q, R
    return float(np.prod(diagonal)), Q, R


def manipulability_and_gradient(J_WF: np.ndarray, p_WF: np.ndarray, upstream: np.ndarray, rows: np.ndarray,
                                columns: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """``(μ, g)`` of the ``rows`` of ``J_WF`` (e.g. ``[3, 4, 5]``: the translation) restricted to
    the velocity ``columns`` (nv booleans, e.g. one arm's joints; None: all), ``g`` (nv) the
    gradient with respect to the velocity directions (``μ̇ = g·v``); ``g = 0`` at a singularity
    (``μ = 0``, where ``μ`` is not differentiable). ``J_WF``: 6×nv finite numbers, ``p_WF``: 3
    finite numbers, ``upstream``: nv×nv booleans (:func:`upstream_coordinates`), ``rows``: distinct
    row indices in [0, 6); anything else (NaN, which would read as a singularity, a row out of
    range) is an :class:`InvalidInput` naming the argument."""
    J_WF, p_WF, upstream, rows = _checked(J_WF, p_WF, upstream, rows, columns)
    nv = J_WF.shape[1]
    cols = np.arange(nv) if columns is None else np.flatnonzero(columns)
    J = J_WF[rows][:, cols]
    mu, Q, R = _factors(J)
    if mu <= 0.0:
        return 0.0, np.zeros(nv)
    dual = solve_triangular(R, Q.T)  # J⁺ᵀ = (J Jᵀ)⁻¹ J = R⁻¹ Qᵀ (J = Rᵀ Qᵀ)
    dJ = jacobian_derivatives(J_WF, p_WF, upstream)[:, rows, :][:, :, cols]
    return mu, mu * np.einsum("ij,kij->k", dual, dJ)


def _checked(J_WF, p_WF, upstream, rows, columns) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The arguments of :func:`manipulability_and_gradient` as arrays, once checked."""
    what = "manipulability_and_gradient"
    J_WF = check_finite(f"{what}: J_WF", J_WF)
    if J_WF.ndim != 2 or J_WF.shape[0] != 6 or J_WF.shape[1] == 0:
        raise InvalidInput(f"{what}: J_WF must be a 6×nv Jacobian (rows ω then v), got shape {J_WF.shape}")
    nv = J_WF.shape[1]
    p_WF = check_finite(f"{what}: p_WF", p_WF, (3,))
    upstream = np.asarray(upstream)
    if upstream.shape != (nv, nv) or upstream.dtype != bool:
        raise InvalidInput(f"{what}: upstream must be {nv}×{nv} booleans (upstream_coordinates(plant)), "
                           f"got {upstream.dtype} of shape {upstream.shape}")
    indices = np.asarray(rows)
    if (indices.ndim != 1 or indices.size == 0 or indices.dtype.kind not in "iu" or indices.min() < 0
            or indices.max() > 5 or np.unique(indices).size != indices.size):
        raise InvalidInput(f"{what}: rows must be distinct row indices of J_WF in [0, 6) (e.g. [3, 4, 5]), got {rows!r:.100}")
    if columns is not None:
        mask = np.asarray(columns)
        if mask.shape != (nv,) or mask.dtype != bool:
            raise InvalidInput(f"{what}: columns must be None or {nv} booleans, got {columns!r:.100}")
    return J_WF, p_WF, upstream, indices


def upstream_coordinates(plant) -> np.ndarray:
    """``upstream[k, i]``: moving velocity coordinate k moves coordinate i's twist (nv×nv booleans;
    see the module docstring)."""
    nv = plant.num_velocities()
    upstream = np.zeros((nv, nv), dtype=bool)
    joints = [plant.get_joint(j) for j in plant.GetJointIndices() if plant.get_joint(j).num_velocities()]
    for joint in joints:
        below = set(plant.GetBodiesKinematicallyAffectedBy([joint.index()]))
        k = slice(joint.velocity_start(), joint.velocity_start() + joint.num_velocities())
        for other in joints:
            if other.index() != joint.index() and other.child_body().index() in below:
                upstream[k, other.velocity_start() : other.velocity_start() + other.num_velocities()] = True
        start = joint.velocity_start()
        for k_own, i_own in _INSIDE_JOINT.get(joint.type_name(), ()):
            upstream[start + k_own, start + i_own] = True
    return upstream


#: Per Drake joint type of more than one velocity, the pairs ``(k, i)`` of its own velocities where
#: moving k moves i's twist. A floating base ``(ω; v)`` (quaternion or roll-pitch-yaw): its
#: translations move its rotations' axes (through the moving origin); a planar joint ``(ẋ, ẏ, θ̇)``:
#: x and y move the axis of θ; a universal joint: the first angle turns the second axis. A ball
#: joint's velocity is its angular velocity about fixed axes through a fixed point: no pair.
_INSIDE_JOINT: dict[str, tuple[tuple[int, int], ...]] = {
    "quaternion_floating": tuple((k, i) for k in range(3, 6) for i in range(3)),
    "rpy_floating": tuple((k, i) for k in range(3, 6) for i in range(3)),
    "planar": ((0, 2), (1, 2)),
    "universal": ((0, 1),),
}
