"""The batched linear algebra against hand-built matrices with known eigenvalues: the
positive-definite test, the eigenvalue floor and the per-episode solve, each with one
bad member in the batch that must not change the others."""
import numpy as np
import pytest

from aligngym.estimators.linalg import (floor_eigenvalues, identity_where_not, positive_definite,
                                        solve_each)


def _with_eigenvalues(values, seed=0):
    """A symmetric matrix Q diag(values) Q^T with a random orthogonal Q, and Q."""
    Q, _ = np.linalg.qr(np.random.default_rng(seed).standard_normal((len(values),) * 2))
    return (Q * np.asarray(values, float)) @ Q.T, Q


@pytest.mark.parametrize("bad", [0, 1, 3])
def test_positive_definite_finds_the_bad_member_wherever_it_sits(bad):
    """Four 3 x 3 members (a batch size other than the matrices' size)."""
    good, _ = _with_eigenvalues([4.0, 1.0, 0.25])
    members = [good.copy() for _ in range(4)]
    members[bad] = _with_eigenvalues([4.0, 1.0, -1e-3], seed=1)[0]
    expected = [b != bad for b in range(4)]
    assert positive_definite(np.stack(members)).tolist() == expected
    members[bad] = good.copy()
    members[bad][0, 1] = np.nan
    assert positive_definite(np.stack(members)).tolist() == expected
    members[bad] = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])  # PSD
    assert positive_definite(np.stack(members)).tolist() == expected
    assert positive_definite(np.stack([good] * 4)).tolist() == [True] * 4


def test_floor_eigenvalues_raises_only_those_below_the_floor():
    """Floor = relative x trace / n: for eigenvalues (6, 2, -1) and relative 0.1, trace 7,
    floor 7/30; the eigenvectors are kept, a positive-definite member is unchanged."""
    indefinite, Q = _with_eigenvalues([6.0, 2.0, -1.0])
    healthy, _ = _with_eigenvalues([3.0, 2.0, 1.0], seed=3)
    out = floor_eigenvalues(np.stack([indefinite, healthy]), relative=0.1)
    np.testing.assert_allclose(out[0], (Q * [6.0, 2.0, 7.0 / 30.0]) @ Q.T, atol=1e-12)
    np.testing.assert_allclose(out[1], healthy, atol=1e-12)
    np.testing.assert_allclose(out[0], out[0].T, atol=0)
    default = floor_eigenvalues(indefinite[None])[0]                    # 1e-12 x 7 / 3
    np.testing.assert_allclose(np.linalg.eigvalsh(default), [7e-12 / 3, 2.0, 6.0],
                               rtol=1e-3, atol=1e-15)
    zero = floor_eigenvalues(-np.eye(3)[None])[0]    # trace < 0: the floor is 1e-300
    assert np.all(np.linalg.eigvalsh(zero) > 0) and np.all(zero.diagonal() <= 1e-299)


def test_solve_each_solves_and_marks_the_singular_member():
    rng = np.random.default_rng(4)
    A = rng.standard_normal((3, 4, 4)) + 4 * np.eye(4)
    B = rng.standard_normal((3, 4, 2))
    X, solved = solve_each(A, B)
    np.testing.assert_allclose(A @ X, B, atol=1e-12)
    assert solved.tolist() == [True] * 3
    A[1, 2, :] = 0.0                                       # exactly singular
    X, solved = solve_each(A, B)
    assert solved.tolist() == [True, False, True]
    assert np.all(np.isnan(X[1]))
    for b in (0, 2):
        np.testing.assert_allclose(X[b], np.linalg.solve(A[b], B[b]), rtol=1e-12)


def test_identity_where_not_puts_the_identity_where_masked():
    """The masked entries are the identity's (1 on the diagonal, 0 off it), the others A's;
    with nothing masked, A itself comes back (no copy)."""
    A = np.arange(2 * 3 * 3, dtype=float).reshape(2, 3, 3) + 10.0
    keep = np.array([True, False])[:, None, None]
    out = identity_where_not(keep, A)
    np.testing.assert_array_equal(out[0], A[0])
    np.testing.assert_array_equal(out[1], np.eye(3))
    cross = np.array([True, False, True])
    out = identity_where_not(cross[:, None] & cross[None, :], A)
    np.testing.assert_array_equal(out[:, 1, 1], [1.0, 1.0])
    np.testing.assert_array_equal(out[:, 0, 1], [0.0, 0.0])
    np.testing.assert_array_equal(out[:, 0, 2], A[:, 0, 2])
    assert identity_where_not(np.ones((2, 1, 1), bool), A) is A
