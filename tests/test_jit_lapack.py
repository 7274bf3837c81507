"""The LAPACK wrappers of compiled code against scipy.linalg.lapack: the same routines, the same bits."""

import subprocess
import sys

import numpy as np
import pytest
from numba.core.errors import TypingError
from scipy.linalg import lapack

from sotdrake.hqp.kernels import lapack as jit_lapack
from tests.conftest import compiled_only


@pytest.mark.parametrize("shape", [(7, 4), (4, 7), (6, 6), (2, 5)])
def test_the_factorizations_are_scipys(shape):
    rng = np.random.default_rng(sum(shape))
    B = rng.normal(size=shape)
    m, n = shape
    k = min(m, n)

    qr, tau = jit_lapack.fortran(B), np.empty(k)
    assert jit_lapack.geqrf(qr, tau) == 0
    reference, reference_tau, _, _ = lapack.dgeqrf(B)
    np.testing.assert_array_equal(qr, reference)
    np.testing.assert_array_equal(tau, reference_tau)

    pivoted, pivots, pivoted_tau = jit_lapack.fortran(B), np.zeros(n, np.int32), np.empty(k)
    assert jit_lapack.geqp3(pivoted, pivots, pivoted_tau) == 0
    reference, reference_pivots, reference_tau, _, _ = lapack.dgeqp3(B)
    np.testing.assert_array_equal(pivoted, reference)
    np.testing.assert_array_equal(pivots, reference_pivots)

    C = rng.normal(size=(m, 3))
    applied = jit_lapack.fortran(C)
    assert jit_lapack.ormqr(qr, tau, applied, True) == 0
    np.testing.assert_allclose(applied, lapack.dormqr("L", "T", qr[:, :k], tau, C, lwork=64)[0], rtol=0, atol=1e-14)
    applied = jit_lapack.fortran(C)
    assert jit_lapack.ormqr(qr, tau, applied, False) == 0
    np.testing.assert_allclose(applied, lapack.dormqr("L", "N", qr[:, :k], tau, C, lwork=64)[0], rtol=0, atol=1e-14)

    if m >= n:
        Q = jit_lapack.fortran(qr)
        assert jit_lapack.orgqr(Q, k, tau) == 0
        np.testing.assert_allclose(Q, lapack.dorgqr(qr, tau)[0], rtol=0, atol=1e-15)
        np.testing.assert_allclose(Q.T @ Q, np.eye(n), atol=1e-14)


def test_triangular_inverse_reads_the_upper_triangle_only_and_says_singular():
    rng = np.random.default_rng(1)
    R = np.triu(rng.normal(size=(5, 5))) + 4.0 * np.eye(5)
    below = R + np.tril(np.full((5, 5), np.nan), -1)  # what lies below is never read
    inverse = jit_lapack.fortran(below)
    assert jit_lapack.trtri_upper(inverse) == 0
    np.testing.assert_allclose(np.triu(inverse), np.linalg.inv(R), rtol=1e-13, atol=1e-15)
    singular = R.copy()
    singular[2, 2] = 0.0
    assert jit_lapack.trtri_upper(jit_lapack.fortran(singular)) == 3  # LAPACK's info: the zero pivot


def _read_only(a):
    a.flags.writeable = False
    return a


_F = jit_lapack.fortran


@compiled_only
@pytest.mark.parametrize(
    "routine, arguments",
    [
        ("geqrf", lambda: (np.ones((3, 2)), np.zeros(2))),  # row-major: read as column-major it is the transpose
        ("geqrf", lambda: (_F(np.ones((3, 2))).astype(np.float32, order="F"), np.zeros(2))),
        ("geqrf", lambda: (_read_only(_F(np.ones((3, 2)))), np.zeros(2))),
        ("geqrf", lambda: (_F(np.ones((3, 2))), np.zeros((2, 1)))),
        ("geqp3", lambda: (_F(np.ones((3, 2))), np.zeros(2, np.int64), np.zeros(2))),
        ("geqp3", lambda: (_F(np.ones((3, 2))), np.zeros(2, np.int32), np.zeros(4)[::2])),
        ("ormqr", lambda: (_F(np.ones((3, 2))), np.zeros(2), np.ones((3, 2)), True)),
        ("trtri_upper", lambda: (np.ones((2, 2)),)),
        ("trtrs_upper", lambda: (_F(np.eye(2)), np.ones((2, 2)))),
    ],
)
def test_an_array_lapack_would_misread_is_refused_before_it_runs(routine, arguments):
    """LAPACK reads memory by its own layout and dtype: any other array is refused as the call is typed,
    with nothing written."""
    values = arguments()
    before = [np.copy(value) for value in values]
    with pytest.raises(TypingError, match="LAPACK wrapper: expected"):
        getattr(jit_lapack, routine)(*values)
    for value, copy in zip(values, before, strict=True):
        np.testing.assert_array_equal(value, copy)


@compiled_only
def test_importing_the_package_compiles_no_lapack_wrapper():
    """The wrappers compile on first use: a fresh install's ``import sotdrake`` compiles none of them."""
    code = (
        "import sotdrake\n"
        "from sotdrake.hqp.kernels import lapack\n"
        "names = ('geqrf', 'geqp3', 'orgqr', 'ormqr', 'trtri_upper', 'trtrs_upper')\n"
        "print(sum(len(getattr(lapack, name).overloads) for name in names))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=600)
    assert out.stdout.split()[-1] == "0"
