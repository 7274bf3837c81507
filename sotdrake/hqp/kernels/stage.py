"""A stage of the hierarchical QP assembled in compiled code (:meth:`.hqp.HierarchicalQP._build`).

The stage of level k in ``z = (y, v)`` (``v``: the level's slacks, if any), from the previous
levels' point ``x0`` and the basis ``Z`` of the directions they leave free (``x = x0 + Z y``)::

    min ½‖M z − t‖²   s.t.   lower ≤ G z ≤ upper      (G: unit rows)

- The *hard rows* first: the bounds of the free components (unit rows of x, given by their
  indices ``free``) and the inequality rows held by the levels above (``held``), projected, ``C =
  [Z[free]; held Z]``, each scaled to unit norm. A row whose projected norm is at most τ times its
  reference norm is constant over the stage and left out (``kept``: the indices of the others).
  Their sides never ask more than ``x0`` achieves: ``c_lower = (min(lo, c·x0) − c·x0) / ‖c Z‖`` (and
  the same above), so ``y = 0`` stays feasible.
- *The minimum-norm stage* (no level): ``M = I``, ``t = −Zᵀx0`` (``‖x0 + Z y‖²`` with ``Z``
  orthonormal).
- *An equality-only level*: ``z = y``, ``M = A_eq Z``, ``t = b_eq − A_eq x0``, with ``√μ I`` below
  when damped (``μ > 0``). A row whose projected norm is at most τ times its norm is fixed by the
  levels above: its ``a Z`` (round-off) is zeroed, so that its residual, constant over the stage,
  pulls ``y`` nowhere (kept, a residual of 1e6 on a round-off row of 1e-10 pulled ``y`` to 1e12
  along the directions another row of the level keeps free, a row of norm 1e-8 say).
- *A level with inequality rows*: ``z = (y, v)`` with one slack ``w_i = ‖a_i‖ v_i`` per inequality
  row (its violation measured on the unit row ``a_i / ‖a_i‖``), ``M = [[A_eq Z, 0], [0, D], [√μ I,
  0]]`` with ``D = diag(‖a_i‖)`` (so the objective is still ``‖A_eq x − b‖² + ‖w‖²``), and the soft
  rows ``lo − a·x0 ≤ a Z y − ‖a‖ v ≤ hi − a·x0`` scaled by ``‖(a Z, −‖a‖)‖``: the slack's coefficient
  stays between ``1/√2`` and 1 whatever the row's norm (with ``w`` as the variable it would be
  ``1/‖(a Z, −1)‖``, below τ on a row of norm beyond 1/τ, and the rank decisions would lose the
  slack); ``v`` starts at each row's violation at ``y = 0`` over ``‖a‖``. A row whose projected norm
  ``‖a Z‖`` is at most τ times its norm ``‖a‖`` is constant over the stage, as a hard row: its ``a Z``
  (round-off, in no meaningful direction) is left out, so only its slack moves (kept, the active set
  could buy a smaller slack with a step of size ``1/‖a Z‖`` along that noise, 1e16 on a random stack
  whose lowest level the levels above fix).

``m_scale`` holds each objective row's reference norm (the level's row norms, ``‖a_i‖`` for the
slacks, ``√μ`` for the damping); the guess of the working set is each hard row's side at the end of
the level above (0 for the soft rows). Imported on the first stage (numba), cached on disk.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .lapack import norm


@njit(cache=True)
def _projected_hard_rows(x0, Z, free, held):
    """``(C, offset)``: the hard rows in y, ``C = [Z[free]; held Z]``, and their values at ``x0``."""
    n_free, m_held, r = free.size, held.shape[0], Z.shape[1]
    C = np.empty((n_free + m_held, r))
    offset = np.empty(n_free + m_held)
    for i in range(n_free):
        C[i] = Z[free[i]]
        offset[i] = x0[free[i]]
    if m_held:
        C[n_free:] = held @ Z
        offset[n_free:] = held @ x0
    return C, offset


@njit(cache=True)
def _objective_kind(M, m_scale):
    """:func:`.active_set.objective_kind`."""
    p = M.shape[1]
    uniform = m_scale.size > 0
    for value in m_scale:
        if value != m_scale[0]:
            uniform = False
            break
    if not (uniform and M.shape[0] == p and m_scale[0] == 1.0 and np.count_nonzero(M) == p):
        return False, uniform
    for i in range(p):
        if M[i, i] != 1.0:
            return False, uniform
    return True, uniform


@njit(cache=True, error_model="numpy")
def build(has_level, A_eq, b_eq, eq_norms, A_in, lower_in, upper_in, in_norms, x0, Z, free, reference, held,
          hard_lower, hard_upper, hard_side, mu, tau):
    """The stage (see the module docstring): ``(M, t, m_scale, G, lower, upper, z0, kept, all_kept,
    guess, m_hard, identity, uniform)``; ``identity, uniform``: the objective's
    :func:`.active_set.objective_kind`. ``has_level`` False: the minimum-norm stage (the level's
    arrays are then not read)."""
    r = Z.shape[1]
    C, offset = _projected_hard_rows(x0, Z, free, held)
    m_all = C.shape[0]
    kept, scale = np.empty(m_all, np.int64), np.empty(m_all)
    m_hard = 0
    for i in range(m_all):
        scale[i] = norm(C[i])
        if scale[i] > tau * reference[i]:  # the others are constant over the stage
            kept[m_hard] = i
            m_hard += 1
    kept = kept[:m_hard]
    m_eq = A_eq.shape[0] if has_level else 0
    m_in = A_in.shape[0] if has_level else 0
    p = r + m_in
    G = np.zeros((m_hard + m_in, p))
    lower, upper = np.empty(m_hard + m_in), np.empty(m_hard + m_in)
    guess = np.zeros(m_hard + m_in, np.int64)
    for j in range(m_hard):
        i = kept[j]
        G[j, :r] = C[i] / scale[i]
        # Never ask more than the previous point achieves (y = 0 stays feasible).
        lower[j] = (min(hard_lower[i], offset[i]) - offset[i]) / scale[i]
        upper[j] = (max(hard_upper[i], offset[i]) - offset[i]) / scale[i]
        guess[j] = hard_side[i]
    z0 = np.zeros(p)
    if not has_level:  # min ‖x0 + Z y‖² (Z orthonormal: ‖y + Zᵀx0‖²)
        return (np.eye(r), -(Z.T @ x0), np.ones(r), G, lower, upper, z0, kept, m_hard == m_all, guess, m_hard,
                True, True)
    m_damped = r if mu > 0.0 else 0
    M = np.zeros((m_eq + m_in + m_damped, p))
    t = np.zeros(M.shape[0])
    m_scale = np.ones(M.shape[0])
    if m_eq:
        M[:m_eq, :r] = A_eq @ Z
        t[:m_eq] = b_eq - A_eq @ x0
        m_scale[:m_eq] = eq_norms
        for i in range(m_eq):  # a row the levels above fix: its residual is constant, its round-off pulls nowhere
            if norm(M[i, :r]) <= tau * eq_norms[i]:
                M[i, :r] = 0.0
    for i in range(m_in):  # w_i = ‖a_i‖ v_i: the slack's term ‖a_i‖² v_i², at the row's reference norm
        M[m_eq + i, r + i] = in_norms[i]
        m_scale[m_eq + i] = in_norms[i]
    for i in range(m_damped):
        M[m_eq + m_in + i, i] = math.sqrt(mu)
        m_scale[m_eq + m_in + i] = math.sqrt(mu)
    if m_in:  # soft rows: lo ≤ a y − ‖a‖ v ≤ hi, scaled to unit norm (‖(a Z, −‖a‖)‖, between ‖a‖ and √2 ‖a‖)
        value = A_in @ x0
        AZ = A_in @ Z
        for i in range(m_in):
            projected, sigma = norm(AZ[i]), in_norms[i]
            if projected > tau * sigma:
                soft_scale = math.sqrt(projected * projected + sigma * sigma)
                G[m_hard + i, :r] = AZ[i] / soft_scale
            else:  # constant over the stage (its projection is round-off): only its slack moves
                soft_scale = sigma
            G[m_hard + i, r + i] = -sigma / soft_scale
            lower[m_hard + i] = (lower_in[i] - value[i]) / soft_scale
            upper[m_hard + i] = (upper_in[i] - value[i]) / soft_scale
            z0[r + i] = min(max(value[i] - upper_in[i], 0.0), value[i] - lower_in[i]) / sigma  # v at y = 0
    identity, uniform = _objective_kind(M, m_scale)  # (with slacks, M holds the block D beside y's columns: not I)
    return M, t, m_scale, G, lower, upper, z0, kept, m_hard == m_all, guess, m_hard, identity and m_in == 0, uniform
