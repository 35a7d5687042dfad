"""The IMU screen's spike candidates compiled with Numba (``screen._spikes``): one pass over
the samples instead of a dozen whole-array temporaries of MBs each (memory-bound, and
slower still with a second process preparing episodes). A module of its own so that
importing the estimators does not load Numba."""
import numpy as np
from numba import njit


@njit(cache=True)
def spike_candidates(rate, floor, size, candidate):
    """For rate (M, 3), non-finite entries read as 0: size (M, 3) <- |second difference|
    (0 at the ends), candidate (M, 3) <- a finite sample whose size is above floor, at
    least its neighbours' (0 beyond the ends) and more than twice the distance between
    its neighbours: the arithmetic of ``screen._spikes`` in the same order."""
    M = rate.shape[0]
    if M == 0:
        return
    across = np.empty(M)                 # how far a sample's neighbours are apart
    for c in range(rate.shape[1]):
        size[0, c], size[M - 1, c] = 0.0, 0.0
        across[0], across[M - 1] = np.inf, np.inf
        for i in range(1, M - 1):
            a, x, b = rate[i - 1, c], rate[i, c], rate[i + 1, c]
            a = a if np.isfinite(a) else 0.0
            x = x if np.isfinite(x) else 0.0
            b = b if np.isfinite(b) else 0.0
            size[i, c] = np.abs(x - 0.5 * (a + b))
            across[i] = np.abs(b - a)
        for i in range(M):
            s = size[i, c]
            before = size[i - 1, c] if i > 0 else 0.0
            after = size[i + 1, c] if i < M - 1 else 0.0
            candidate[i, c] = (s > floor and s >= before and s >= after
                               and across[i] < 0.5 * s and np.isfinite(rate[i, c]))
