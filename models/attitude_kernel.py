"""``attitude.quat_cumprod``'s scan compiled with Numba: the same passes and the same
arithmetic, in place, one sweep over the samples a pass instead of a dozen whole-array
temporaries (the NumPy scan of a 600 s episode at 100 Hz made each pass's products and
norms as arrays of MBs: memory-bound, and twice as slow with a second process doing the
same). A module of its own so that importing the models does not load Numba."""
import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")   # a zero norm gives NaN, as NumPy's
def quat_scan(out):
    """Hillis-Steele running products of out (n, m, 4) along its first axis, in place: at
    each pass (step 1, 2, 4 ...) out[i] <- out[i - step] * out[i] for i >= step (the
    previous pass's values: i is taken from the top down), then normalised; each product
    and norm evaluated as ``attitude.quat_mul`` and NumPy's sum of squares do."""
    n, m = out.shape[0], out.shape[1]
    step = 1
    while step < n:
        for i in range(n - 1, step - 1, -1):
            for j in range(m):
                pw, px, py, pz = out[i - step, j, 0], out[i - step, j, 1], \
                    out[i - step, j, 2], out[i - step, j, 3]
                qw, qx, qy, qz = out[i, j, 0], out[i, j, 1], out[i, j, 2], out[i, j, 3]
                r0 = pw * qw - px * qx - py * qy - pz * qz
                r1 = pw * qx + px * qw + py * qz - pz * qy
                r2 = pw * qy - px * qz + py * qw + pz * qx
                r3 = pw * qz + px * qy - py * qx + pz * qw
                norm = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3)
                out[i, j, 0], out[i, j, 1], out[i, j, 2], out[i, j, 3] = \
                    r0 / norm, r1 / norm, r2 / norm, r3 / norm
        step *= 2
