"""Centroidal momentum of a floating-base robot, from the floating base's rows of the dynamics.

The centroidal momentum ``h_G = (k_G; l) = A_G(q) v`` is the robot's spatial momentum about its
centre of mass G, expressed in the world frame: ``k_G`` the angular momentum about G (kg·m²/s),
``l = m ṗ_G`` the linear momentum (kg·m/s). (Drake's ``SpatialMomentum`` order: angular first.)

Drake's floating base has the velocity ``(ω_WB; v_WBo)`` (world frame, ``v_WBo`` the velocity of
the base's origin Bo), and the kinetic energy's partial derivatives with respect to it are the
robot's spatial momentum about Bo: ``∂T/∂ω_WB = k_Bo`` (every point moves by ``δω × (p − p_Bo)``)
and ``∂T/∂v_WBo = l``. So the base's six rows of the mass matrix give ``M_b v = (k_Bo; l)``, and
shifting the moment from Bo to G, ``k_G = k_Bo + (p_Bo − p_G) × l``::

    A_G = X M_b,    X = [[I, [p_Bo − p_G]×], [0, I]]

(Wensing and Orin, 2016). The same shift maps the base rows of the bias ``C(q, v) v`` (without
gravity or joint damping), which are the spatial force about Bo that moves the robot at ``q̈ = 0``,
to the rate of the centroidal momentum at ``q̈ = 0``: ``Ȧ_G v = X (C v)_b``; then
``ḣ_G = A_G q̈ + Ȧ_G v``. A robot without a floating base has no such rows: the functions here
need one (:class:`~sotdrake.exceptions.InvalidInput` otherwise).
"""

from __future__ import annotations

import numpy as np

from .configuration import Layout
from .exceptions import InvalidInput


def _shift(p_WBo: np.ndarray, p_WG: np.ndarray) -> np.ndarray:
    """``X``: a spatial momentum ``(k_Bo; l)`` about Bo to ``(k_G; l)`` about G."""
    r = np.asarray(p_WBo, dtype=float) - np.asarray(p_WG, dtype=float)
    X = np.eye(6)
    X[0:3, 3:6] = [[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]]
    return X


def base_rows(layout: Layout) -> slice:
    """The velocity rows of the floating base ``(ω_WB; v_WBo)``; :class:`InvalidInput` without one."""
    if layout.base_v is None or layout.base_q is None:
        raise InvalidInput("the centroidal momentum needs a floating base (the robot's base is fixed or planar): "
                           "its momentum is then carried by whatever holds the base")
    return slice(layout.base_v, layout.base_v + 6)


def base_origin(q: np.ndarray, layout: Layout) -> np.ndarray:
    """``p_WBo``: the floating base's position in ``q`` (Drake's ``(qw, qx, qy, qz, x, y, z)``)."""
    base_rows(layout)
    start = int(layout.base_q) + 4  # type: ignore[arg-type]  # (checked by base_rows)
    return np.asarray(q[start : start + 3], dtype=float)


def centroidal_momentum_matrix(M: np.ndarray, q: np.ndarray, p_WG: np.ndarray, layout: Layout) -> np.ndarray:
    """``A_G`` (6×nv, rows ``(k_G; l)``, world frame) from the mass matrix ``M`` at ``q`` and the
    centre of mass ``p_WG`` (see the module docstring)."""
    return _shift(base_origin(q, layout), p_WG) @ M[base_rows(layout)]


def centroidal_momentum_terms(M: np.ndarray, Cv: np.ndarray, q: np.ndarray, v: np.ndarray, p_WG: np.ndarray,
                              layout: Layout) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A_G, Ȧ_G v, h_G)`` at the state ``(q, v)``: ``Cv`` is Drake's ``CalcBiasTerm``
    (``C(q, v) v``, without gravity or damping)."""
    rows = base_rows(layout)
    X = _shift(base_origin(q, layout), p_WG)
    A = X @ M[rows]
    return A, X @ Cv[rows], A @ v
