"""Paper 002's Euler-error process map compiled with Numba: one explicit-midpoint step
(``euler_kinematics.midpoint_step``) of every integration point of every episode in one loop,
the arithmetic of ``euler_kinematics._dynamics`` written per point in the same order: the
same numbers to the bit where NumPy's float64 sine and cosine are the C library's (x86-64
without AVX-512, as on the reference machine), within an ulp of them where NumPy has its
own (AVX-512); a test. A module of its own so that importing the estimators does not
load Numba before a filter runs."""
import numpy as np
from numba import njit


@njit(cache=True)
def _rates(x0, x1, x2, x5, x6, x7, x8, x9, C, f, w):
    """x_dot[0:5] of ALGORITHMS (3.5) at one point (``euler_kinematics._dynamics``)."""
    sE, cE = np.sin(x0), np.cos(x0)
    sN, cN = np.sin(x1), np.cos(x1)
    sU, cU = np.sin(x2), np.cos(x2)
    sEsN, sEcN = sE * sN, sE * cN
    c00, c01, c02 = cU * cN - sU * sEsN, -sU * cE, cU * sN + sU * sEcN
    c10, c11, c12 = sU * cN + cU * sEsN, cU * cE, sU * sN - cU * sEcN
    c20, c21, c22 = -cE * sN, sE, cE * cN
    w0, w1, w2 = w[0], w[1], w[2]
    ct0 = c00 * w0 + c10 * w1 + c20 * w2
    ct1 = c01 * w0 + c11 * w1 + c21 * w2
    ct2 = c02 * w0 + c12 * w1 + c22 * w2
    r0 = w0 - ct0 - (C[0, 0] * x7 + C[0, 1] * x8 + C[0, 2] * x9)
    r1 = w1 - ct1 - (C[1, 0] * x7 + C[1, 1] * x8 + C[1, 2] * x9)
    r2 = w2 - ct2 - (C[2, 0] * x7 + C[2, 1] * x8 + C[2, 2] * x9)
    a = sN * r0 - cN * r2
    out0 = cN * r0 + sN * r2
    out1 = r1 + a * sE / cE
    out2 = -a / cE
    d0 = f[0] - (C[0, 0] * x5 + C[0, 1] * x6)
    d1 = f[1] - (C[1, 0] * x5 + C[1, 1] * x6)
    d2 = f[2] - (C[2, 0] * x5 + C[2, 1] * x6)
    out3 = f[0] - (cN * d0 + sN * d2)
    out4 = f[1] - (sEsN * d0 + cE * d1 - sEcN * d2)
    return out0, out1, out2, out3, out4


@njit(cache=True)
def midpoint_points(x, T, C_b_p, f_p, omega_ie, out):
    """out (B, P, 10) = x + T f(x + T/2 f(x)) for points x (B, P, 10) with each episode's
    inputs held: C_b_p (B, 3, 3), f_p (B, 3) m/s^2, omega_ie (B, 3) rad/s; T s."""
    half = 0.5 * T
    for b in range(x.shape[0]):
        C, f, w = C_b_p[b], f_p[b], omega_ie[b]
        for p in range(x.shape[1]):
            xp = x[b, p]
            k0, k1, k2, k3, k4 = _rates(xp[0], xp[1], xp[2], xp[5], xp[6], xp[7], xp[8],
                                        xp[9], C, f, w)
            # the biases' midpoint is x + T/2 * 0 (as the array code adds it)
            m0, m1, m2, m3, m4 = _rates(xp[0] + half * k0, xp[1] + half * k1,
                                        xp[2] + half * k2, xp[5] + half * 0.0,
                                        xp[6] + half * 0.0, xp[7] + half * 0.0,
                                        xp[8] + half * 0.0, xp[9] + half * 0.0, C, f, w)
            o = out[b, p]
            o[0], o[1], o[2] = xp[0] + T * m0, xp[1] + T * m1, xp[2] + T * m2
            o[3], o[4] = xp[3] + T * m3, xp[4] + T * m4
            for i in range(5, 10):       # biases: x_dot = 0, x + T * 0
                o[i] = xp[i] + T * 0.0
