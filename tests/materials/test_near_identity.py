"""The series of :mod:`parmpm.materials.plasticity.near_identity` against the eigen-decomposition
(numpy's ``eigh``, an independent LAPACK solver): ``ln(I + X)`` and ``exp D`` to round-off over the
whole range they serve, including repeated eigenvalues and ``X = 0``: to round-off against the
plain Taylor series ``ln(I + X) = X − X²/2 + X³/3 − …`` and ``Σ Dᵏ/k!`` summed to 80 terms in
extended precision (``np.longdouble``, 64-bit mantissa), and to ``eigh``'s own accuracy against the
eigen-decomposition taken about the identity (``eigh(X)`` with ``log1p``, ``eigh(D)`` with
``expm1``)."""
import numpy as np
import pytest
from numba import njit

from parmpm.materials.plasticity.near_identity import (RHO_MAX, exp_near_zero,
                                                       log_near_identity)

ORDER = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


@njit(cache=False)
def _log(x):
    return log_near_identity(x[0, 0], x[1, 1], x[2, 2], x[0, 1], x[0, 2], x[1, 2])


@njit(cache=False)
def _exp(x):
    return exp_near_zero(x[0, 0], x[1, 1], x[2, 2], x[0, 1], x[0, 2], x[1, 2])


def _full(six):
    out = np.empty((3, 3))
    for v, (r, c) in zip(six, ORDER):
        out[r, c] = out[c, r] = v
    return out


def _taylor(A, log):
    """Extended-precision Taylor sum of ``ln(I + A)`` (``log``) or ``exp A − I``."""
    A = A.astype(np.longdouble)
    term, out = np.eye(3, dtype=np.longdouble), np.zeros((3, 3), dtype=np.longdouble)
    for k in range(1, 81):
        term = term @ A
        out += (-term if k % 2 == 0 else term) / k if log else term
        if not log:
            term = term / (k + 1)
    return out


def _by_eigh(A, f):
    w, V = np.linalg.eigh(A)
    return (V * f(w)) @ V.T


def _samples(rng, norm, n=200):
    """Symmetric matrices of Frobenius norm ``norm``: random, with a double and a triple
    eigenvalue, diagonal and uniaxial."""
    out = []
    for _ in range(n):
        A = rng.normal(size=(3, 3))
        out.append(A + A.T)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    out += [Q @ np.diag([1.0, 1.0, -2.0]) @ Q.T, np.eye(3), -np.eye(3), np.diag([1.0, -1.0, 0.0]),
            np.diag([1.0, 0.0, 0.0]), Q @ np.diag([-1.0, 0.0, 0.0]) @ Q.T]
    return [norm * A / np.linalg.norm(A) for A in out]


@pytest.mark.parametrize("norm", [RHO_MAX, RHO_MAX / 10, 1e-4, 1e-9])
def test_log_matches_eigh(norm):
    rng = np.random.default_rng(3)
    for X in _samples(rng, norm):
        got = _full(_log(X))
        ref = _taylor(X, log=True)
        assert float(np.abs(got - ref).max()) <= 1e-15 * float(np.abs(ref).max())
        eig = _by_eigh(X, np.log1p)  # LAPACK's own error is a few 1e-15 of the result
        assert np.abs(got - eig).max() <= 5e-15 * np.abs(eig).max()


def test_log_of_identity_is_zero():
    assert _log(np.zeros((3, 3))) == (0.0,) * 6


@pytest.mark.parametrize("norm", [0.25, 0.05, 1e-6])
def test_exp_matches_eigh(norm):
    rng = np.random.default_rng(4)
    for D in _samples(rng, norm):
        got = _full(_exp(D)) - np.eye(3)  # entries near 1: known to an ulp of 1
        ref = _taylor(D, log=False)
        assert float(np.abs(got - ref).max()) <= 2.5e-16
        assert np.abs(got - _by_eigh(D, np.expm1)).max() <= 1e-15


def test_exp_undoes_log():
    rng = np.random.default_rng(5)
    for X in _samples(rng, RHO_MAX, n=50):
        back = _full(_exp(_full(_log(X))))
        assert np.abs(back - np.eye(3) - X).max() <= 1e-15


def test_log_beyond_its_range_is_not_silently_served():
    """The truncation is sized for :data:`RHO_MAX`: at 10× it the error is far above round-off,
    which is why the pass takes the eigen path there."""
    X = np.diag([0.9, -0.9, 0.0])
    err = np.abs(_full(_log(X)) - _by_eigh(X, np.log1p)).max()
    assert err > 1e-8
