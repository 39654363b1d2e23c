"""The symmetric 3×3 eigen-solver of the return maps (:mod:`parmpm.materials.plasticity.spectral`)
against ``numpy.linalg.eigh``, compiled and through ``.py_func``: random matrices of mixed sign and
scale, and the degenerate ones a plastic body meets — the identity, a multiple of it, a double
eigenvalue, diagonal and block-diagonal (plane strain) matrices, off-diagonals of 1e-12 over equal
diagonals. Eigenvalues to 1e-14 of the matrix norm, ``V`` orthonormal to 1e-14 and
``V diag(w) Vᵀ = A`` (:func:`from_principal`) to 1e-14: with repeated eigenvalues the vectors are
not unique, so they are judged by what they reconstruct, not compared with numpy's.
"""
import numpy as np
import pytest

from parmpm.materials.plasticity.spectral import MAX_SWEEPS, from_principal, sym_eig3


def rotation(rng):
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    return Q


def matrices():
    rng = np.random.default_rng(42)
    out = [("identity", np.eye(3)), ("zero", np.zeros((3, 3))), ("4.5 I", 4.5 * np.eye(3)),
           ("diagonal", np.diag([3.0, -1.0, 2.0])), ("diagonal, equal pair", np.diag([2.0, 1.0, 2.0])),
           ("plane strain", np.array([[2.0, 0.7, 0.0], [0.7, 1.1, 0.0], [0.0, 0.0, 1.0]])),
           ("1e-12 off-diagonal", np.eye(3) + 1e-12 * (np.ones((3, 3)) - np.eye(3))),
           ("1e-12 off, one pair", np.array([[1.0, 1e-12, 0.0], [1e-12, 1.0, 0.0], [0.0, 0.0, 5.0]]))]
    for k in range(3):  # double eigenvalues in random axes
        Q = rotation(rng)
        out.append((f"double {k}", Q @ np.diag([1.5, 1.5, 0.2 + k]) @ Q.T))
    for k in range(20):
        A = rng.standard_normal((3, 3)) * 10.0 ** rng.uniform(-3, 3)
        out.append((f"random {k}", A + A.T))
    Q = rotation(rng)
    out.append(("b_e of a stretch 1e3:1", Q @ np.diag([1e3, 1.0, 1e-3]) @ Q.T))
    return out


CASES = matrices()


@pytest.mark.parametrize("jit", [True, False], ids=["jit", "py_func"])
@pytest.mark.parametrize("name,A", CASES, ids=[c[0] for c in CASES])
def test_against_eigh(jit, name, A):
    eig = sym_eig3 if jit else sym_eig3.py_func
    rebuild = from_principal if jit else from_principal.py_func
    A = np.ascontiguousarray((A + A.T) / 2)
    before = A.copy()
    w, V, back = np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3))
    sweeps = eig(A, w, V)
    norm = max(np.abs(A).max(), 1e-300)
    assert sweeps <= 10, sweeps
    assert np.array_equal(A, before)  # the input is left as it is
    assert np.abs(w - np.linalg.eigh(A)[0]).max() <= 1e-14 * norm
    assert np.all(np.diff(w) >= 0.0)
    assert np.abs(V.T @ V - np.eye(3)).max() <= 1e-14
    rebuild(w, V, back)
    assert np.abs(back - A).max() <= 1e-14 * norm


def test_nan_gives_up():
    """A NaN matrix neither hangs nor claims convergence."""
    A = np.eye(3)
    A[0, 1] = A[1, 0] = np.nan
    w, V = np.zeros(3), np.zeros((3, 3))
    assert sym_eig3(A, w, V) == MAX_SWEEPS + 1


# --- the closed-form solver of the plastic pass (parmpm.materials.plasticity.closed_form_eigen)
NEAR_IDENTITY = [(f"near identity {k}", m) for k, m in enumerate(
    (lambda rng: [np.eye(3) + s * (lambda B: B + B.T)(rng.standard_normal((3, 3)))
                  for s in (1e-3, 1e-6, 1e-9, 1e-13)])(np.random.default_rng(5)))]


@pytest.mark.parametrize("jit", [True, False], ids=["jit", "py_func"])
@pytest.mark.parametrize("name,A", CASES + NEAR_IDENTITY,
                         ids=[c[0] for c in CASES + NEAR_IDENTITY])
def test_closed_form_against_eigh(jit, name, A):
    """The same bounds as Jacobi's, and on near-identity ``b_e`` (the elastic metal's) the
    eigenvalues to 1e-15 absolute: the shift to the deviator loses nothing."""
    from parmpm.materials.plasticity.closed_form_eigen import sym_eig3_closed

    eig = sym_eig3_closed if jit else sym_eig3_closed.py_func
    A = np.ascontiguousarray((A + A.T) / 2)
    before = A.copy()
    w, V, back = np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3))
    eig(A, w, V)
    norm = max(np.abs(A).max(), 1e-300)
    assert np.array_equal(A, before)
    assert np.abs(w - np.linalg.eigh(A)[0]).max() <= 1e-14 * norm
    assert np.all(np.diff(w) >= 0.0)
    assert np.abs(V.T @ V - np.eye(3)).max() <= 1e-14
    from_principal(w, V, back)
    assert np.abs(back - A).max() <= 1e-14 * norm
    if name.startswith("near identity"):
        assert np.abs(w - np.linalg.eigh(A)[0]).max() <= 1e-15


def test_closed_form_nan_is_nan():
    from parmpm.materials.plasticity.closed_form_eigen import sym_eig3_closed

    A = np.eye(3)
    A[0, 1] = A[1, 0] = np.nan
    w, V = np.zeros(3), np.zeros((3, 3))
    sym_eig3_closed(A, w, V)
    assert np.isnan(w).all()
