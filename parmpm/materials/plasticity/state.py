"""A plastic particle's state row (the store's optional ``plastic`` field), in one place for
the pass that updates it, the store that carries it and the outputs that read it: the inverse
plastic right Cauchy–Green tensor ``C_p⁻¹`` (symmetric, entries in the order :data:`SYM`), the
equivalent plastic strain ``ε̄p`` and the plastic work done on the particle so far per unit
reference volume ``W_p`` (the energy account's dissipation).
"""
import numpy as np

#: ``C_p⁻¹``'s entries in a state row: (row, column) of columns 0–5
SYM = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
#: the columns of ε̄p and W_p, and the row's width
STATE_EPSP, STATE_WORK, STATE_WIDTH = 6, 7, 8


def initial_state(n: int) -> np.ndarray:
    """``n`` virgin rows: ``C_p⁻¹ = I``, no plastic strain or work."""
    s = np.zeros((n, STATE_WIDTH))
    s[:, :3] = 1.0
    return s


def unpack(rows: np.ndarray) -> np.ndarray:
    """``C_p⁻¹`` of state ``rows`` (n, STATE_WIDTH) as (n, 3, 3) matrices (outputs, tests)."""
    out = np.empty((rows.shape[0], 3, 3))
    for q, (r, c) in enumerate(SYM):
        out[:, r, c] = rows[:, q]
        out[:, c, r] = rows[:, q]
    return out


def plastic_volume(rows: np.ndarray) -> np.ndarray:
    """``ln J_p = −½ ln det C_p⁻¹`` of state ``rows``: the plastic volume change (0 on a virgin
    or elastic particle)."""
    return -0.5 * np.log(np.linalg.det(unpack(rows))) if rows.shape[0] else np.zeros(0)
