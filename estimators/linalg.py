"""Batched linear algebra that tolerates a bad member: each function acts on a batch of B
independent episodes and reports, rather than raises on, a member that is not positive
definite or is singular, so that one episode's numerical trouble never stops the rest."""
from __future__ import annotations

import numpy as np


def identity_where_not(keep: np.ndarray, A: np.ndarray) -> np.ndarray:
    """A (..., n, n) with the identity's entries where keep (broadcast to A) is False; A
    itself, not a copy, where keep is True throughout (the usual case: no masking)."""
    return A if keep.all() else np.where(keep, A, np.eye(A.shape[-1]))


def positive_definite(A: np.ndarray) -> np.ndarray:
    """(B,) True where A[b] is finite and positive definite."""
    ok = np.all(np.isfinite(A), axis=(-2, -1))
    try:
        np.linalg.cholesky(identity_where_not(ok[:, None, None], A))
        return ok
    except np.linalg.LinAlgError:
        for b in np.flatnonzero(ok):
            try:
                np.linalg.cholesky(A[b])
            except np.linalg.LinAlgError:
                ok[b] = False
        return ok


def floor_eigenvalues(P: np.ndarray, relative: float = 1e-12) -> np.ndarray:
    """P (B, n, n) with eigenvalues floored at relative x trace / n."""
    vals, vecs = np.linalg.eigh(P)
    floor = relative * np.maximum(np.trace(P, axis1=-2, axis2=-1), 0.0) / P.shape[-1]
    vals = np.maximum(vals, np.maximum(floor, 1e-300)[:, None])
    return (vecs * vals[:, None, :]) @ np.swapaxes(vecs, -1, -2)


def solve_each(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A^-1 B for a batch (A (K, n, n), B (K, n, m)) and solved (K,): False where A is
    singular to working precision (its rows NaN); one batched solve when none is."""
    try:
        return np.linalg.solve(A, B), np.ones(A.shape[0], bool)
    except np.linalg.LinAlgError:
        X, solved = np.full(np.shape(B), np.nan), np.zeros(A.shape[0], bool)
        for b in range(A.shape[0]):
            try:
                X[b], solved[b] = np.linalg.solve(A[b], B[b]), True
            except np.linalg.LinAlgError:
                pass
        return X, solved
