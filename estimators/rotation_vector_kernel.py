"""Paper 004's error-state process map compiled with Numba: the classical Runge-Kutta step
of ``rotation_vector.RotationVectorGnssModel.transition`` over every point of every episode
in one loop, each stage's derivative (``rotation_vector_dynamics.st_derivative`` or
``classic_derivative``, with the earth model of ``models.earth``) written per point in the
order of the NumPy expressions. The NumPy functions stay the reference
(``rotation_vector.numpy_runge_kutta_step``): the two agree within 4e-12 of each
component's largest increment (a test; NumPy's AVX-512 tangent and power differ from the C
library's by an ulp). Notation as in (6.1)-(6.5): unmarked (the velocity v~), the INS's
quantities; primed, those at the true position and velocity the error state implies. A module of its own so
that importing the estimators does not load Numba before a filter runs."""
import numpy as np
from numba import njit

from aligngym.models.earth import _K_SOMIGLIANA, _M, A, E2, F, GAMMA_EQUATOR, OMEGA_IE


@njit(cache=True)
def _truth_rates(lat, h, v0, v1, v2, out):
    """The earth rate, transport rate and gravity (ENU) at a true latitude (rad), height
    (m) and velocity (m/s), and d(L, lambda, h)/dt there: out (12,) = omega_ie (3),
    omega_en (3), g (3), position rate (3) (``models.earth``; ``_position_rate``)."""
    s = np.sin(lat)
    s2 = s * s
    w = np.sqrt(1.0 - E2 * s2)
    R_M, R_N = A * (1.0 - E2) / w ** 3.0, A / w
    R_Mh, R_Nh = R_M + h, R_N + h
    c = np.cos(lat)
    out[0], out[1], out[2] = 0.0, OMEGA_IE * c, OMEGA_IE * s
    out[3], out[4], out[5] = -v1 / R_Mh, v0 / R_Nh, v0 * np.tan(lat) / R_Nh
    gamma0 = GAMMA_EQUATOR * (1.0 + _K_SOMIGLIANA * s2) / np.sqrt(1.0 - E2 * s2)
    gamma = gamma0 * (1.0 - 2.0 / A * (1.0 + F + _M - 2.0 * F * s2) * h
                      + 3.0 * (h * h) / A ** 2)
    out[6], out[7], out[8] = 0.0, 0.0, -gamma
    out[9], out[10], out[11] = v1 / R_Mh, v0 / (R_Nh * c), v2


@njit(cache=True)
def _derivative(x, transformed, C, f, v, w_ie, w_en, g, rate, lat, h, Cp, t, out):
    """x_dot (15,) at one point x (15,) = [phi (rad), dv (the ST form if transformed, else
    the classic one; m/s, ENU), dL, dlambda (rad), dh (m), eps (rad/s), nabla (m/s^2), body
    frame], for one instant's INS quantities: C = C_b^p (3, 3); f (3,) the bias-compensated
    specific force, body frame, m/s^2; v (3,) m/s ENU; w_ie, w_en (3,) rad/s and g (3,)
    m/s^2 ENU at the INS's position; rate (3,) its d(L, lambda, h)/dt (rad/s, rad/s, m/s);
    lat (rad), h (m). Cp (3, 3) and t (12,) are scratch: C_p^n, and ``_truth_rates``'
    omega_ie' (t[0:3]), omega_en' (t[3:6]), g' (t[6:9]) and position rate' (t[9:12])."""
    p0, p1, p2 = x[0], x[1], x[2]
    angle = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    # C_p^n = exp([phi x]) through the quaternion (models.attitude.rotvec_to_dcm)
    qw = np.cos(0.5 * angle)
    # sin(angle / 2) / angle as NumPy's sinc(angle / 2 pi) / 2 computes it, to its bits
    y = np.pi * (angle / (2.0 * np.pi)) if angle != 0.0 else np.pi * 1.0e-20
    s = 0.5 * (np.sin(y) / y)
    qx, qy, qz = s * p0, s * p1, s * p2
    Cp[0, 0] = 1 - 2 * (qy * qy + qz * qz)
    Cp[0, 1] = 2 * (qx * qy - qw * qz)
    Cp[0, 2] = 2 * (qx * qz + qw * qy)
    Cp[1, 0] = 2 * (qx * qy + qw * qz)
    Cp[1, 1] = 1 - 2 * (qx * qx + qz * qz)
    Cp[1, 2] = 2 * (qy * qz - qw * qx)
    Cp[2, 0] = 2 * (qx * qz - qw * qy)
    Cp[2, 1] = 2 * (qy * qz + qw * qx)
    Cp[2, 2] = 1 - 2 * (qx * qx + qy * qy)
    d0, d1, d2 = x[3], x[4], x[5]
    if transformed:     # the classic velocity error (6.3): (I - C_p^n) v~ + C_p^n dv_ST
        d0, d1, d2 = ((v[0] - (Cp[0, 0] * v[0] + Cp[0, 1] * v[1] + Cp[0, 2] * v[2]))
                      + (Cp[0, 0] * x[3] + Cp[0, 1] * x[4] + Cp[0, 2] * x[5]),
                      (v[1] - (Cp[1, 0] * v[0] + Cp[1, 1] * v[1] + Cp[1, 2] * v[2]))
                      + (Cp[1, 0] * x[3] + Cp[1, 1] * x[4] + Cp[1, 2] * x[5]),
                      (v[2] - (Cp[2, 0] * v[0] + Cp[2, 1] * v[1] + Cp[2, 2] * v[2]))
                      + (Cp[2, 0] * x[3] + Cp[2, 1] * x[4] + Cp[2, 2] * x[5]))
    vt0, vt1, vt2 = v[0] - d0, v[1] - d1, v[2] - d2
    _truth_rates(lat - x[6], h - x[8], vt0, vt1, vt2, t)
    # (6.1): phi_dot = J_r^-1(phi) [w_ie + w_en - C_n^p (w_ie' + w_en') - C_b^p eps]
    u0, u1, u2 = t[0] + t[3], t[1] + t[4], t[2] + t[5]
    e0 = C[0, 0] * x[9] + C[0, 1] * x[10] + C[0, 2] * x[11]
    e1 = C[1, 0] * x[9] + C[1, 1] * x[10] + C[1, 2] * x[11]
    e2 = C[2, 0] * x[9] + C[2, 1] * x[10] + C[2, 2] * x[11]
    o0 = ((w_ie[0] + w_en[0]) - (Cp[0, 0] * u0 + Cp[1, 0] * u1 + Cp[2, 0] * u2)) - e0
    o1 = ((w_ie[1] + w_en[1]) - (Cp[0, 1] * u0 + Cp[1, 1] * u1 + Cp[2, 1] * u2)) - e1
    o2 = ((w_ie[2] + w_en[2]) - (Cp[0, 2] * u0 + Cp[1, 2] * u1 + Cp[2, 2] * u2)) - e2
    n0 = C[0, 0] * x[12] + C[0, 1] * x[13] + C[0, 2] * x[14]      # C_b^p nabla
    n1 = C[1, 0] * x[12] + C[1, 1] * x[13] + C[1, 2] * x[14]
    n2 = C[2, 0] * x[12] + C[2, 1] * x[13] + C[2, 2] * x[14]
    if angle < 1e-4:
        k = 1.0 / 12.0 + angle ** 2 / 720.0
    else:
        k = 1.0 / angle ** 2 - (1.0 + np.cos(angle)) / (2.0 * angle * np.sin(angle))
    # J = I + [phi x]/2 + k [phi x]^2, [phi x]^2 = phi phi^T - |phi|^2 I
    K00, K11, K22 = -(p2 * p2) - p1 * p1, -(p2 * p2) - p0 * p0, -(p1 * p1) - p0 * p0
    K01, K02, K12 = p0 * p1, p0 * p2, p1 * p2
    out[0] = (1.0 + k * K00) * o0 + (-0.5 * p2 + k * K01) * o1 + (0.5 * p1 + k * K02) * o2
    out[1] = (0.5 * p2 + k * K01) * o0 + (1.0 + k * K11) * o1 + (-0.5 * p0 + k * K12) * o2
    out[2] = (-0.5 * p1 + k * K02) * o0 + (0.5 * p0 + k * K12) * o1 + (1.0 + k * K22) * o2
    if transformed:
        # (6.4): C_b^p nabla + g - C_n^p g' - (w_ie - C_n^p w_ie') x v~ + v~ x (C_b^p eps)
        #        - (w_ie + w_en + C_n^p w_ie' - C_b^p eps) x dv_ST
        G0 = Cp[0, 0] * t[6] + Cp[1, 0] * t[7] + Cp[2, 0] * t[8]
        G1 = Cp[0, 1] * t[6] + Cp[1, 1] * t[7] + Cp[2, 1] * t[8]
        G2 = Cp[0, 2] * t[6] + Cp[1, 2] * t[7] + Cp[2, 2] * t[8]
        W0 = Cp[0, 0] * t[0] + Cp[1, 0] * t[1] + Cp[2, 0] * t[2]
        W1 = Cp[0, 1] * t[0] + Cp[1, 1] * t[1] + Cp[2, 1] * t[2]
        W2 = Cp[0, 2] * t[0] + Cp[1, 2] * t[1] + Cp[2, 2] * t[2]
        a0, a1, a2 = w_ie[0] - W0, w_ie[1] - W1, w_ie[2] - W2
        b0 = ((w_ie[0] + w_en[0]) + W0) - e0
        b1 = ((w_ie[1] + w_en[1]) + W1) - e1
        b2 = ((w_ie[2] + w_en[2]) + W2) - e2
        x3, x4, x5 = x[3], x[4], x[5]
        out[3] = ((((n0 + g[0]) - G0) - (a1 * v[2] - a2 * v[1]))
                  + (v[1] * e2 - v[2] * e1)) - (b1 * x5 - b2 * x4)
        out[4] = ((((n1 + g[1]) - G1) - (a2 * v[0] - a0 * v[2]))
                  + (v[2] * e0 - v[0] * e2)) - (b2 * x3 - b0 * x5)
        out[5] = ((((n2 + g[2]) - G2) - (a0 * v[1] - a1 * v[0]))
                  + (v[0] * e1 - v[1] * e0)) - (b0 * x4 - b1 * x3)
    else:
        # (6.2): f^p - C_p^n f^p + C_p^n C_b^p nabla - (2 w_ie + w_en) x v~
        #        + (2 w_ie' + w_en') x v' + g - g' (': at the true position and velocity)
        fp0 = C[0, 0] * f[0] + C[0, 1] * f[1] + C[0, 2] * f[2]
        fp1 = C[1, 0] * f[0] + C[1, 1] * f[1] + C[1, 2] * f[2]
        fp2 = C[2, 0] * f[0] + C[2, 1] * f[1] + C[2, 2] * f[2]
        a0, a1, a2 = 2 * w_ie[0] + w_en[0], 2 * w_ie[1] + w_en[1], 2 * w_ie[2] + w_en[2]
        b0, b1, b2 = 2 * t[0] + t[3], 2 * t[1] + t[4], 2 * t[2] + t[5]
        out[3] = (((((fp0 - (Cp[0, 0] * fp0 + Cp[0, 1] * fp1 + Cp[0, 2] * fp2))
                     + (Cp[0, 0] * n0 + Cp[0, 1] * n1 + Cp[0, 2] * n2))
                    - (a1 * v[2] - a2 * v[1])) + (b1 * vt2 - b2 * vt1)) + g[0]) - t[6]
        out[4] = (((((fp1 - (Cp[1, 0] * fp0 + Cp[1, 1] * fp1 + Cp[1, 2] * fp2))
                     + (Cp[1, 0] * n0 + Cp[1, 1] * n1 + Cp[1, 2] * n2))
                    - (a2 * v[0] - a0 * v[2])) + (b2 * vt0 - b0 * vt2)) + g[1]) - t[7]
        out[5] = (((((fp2 - (Cp[2, 0] * fp0 + Cp[2, 1] * fp1 + Cp[2, 2] * fp2))
                     + (Cp[2, 0] * n0 + Cp[2, 1] * n1 + Cp[2, 2] * n2))
                    - (a0 * v[1] - a1 * v[0])) + (b0 * vt1 - b1 * vt0)) + g[2]) - t[8]
    # (6.5): the INS's position rate less the true one
    out[6], out[7], out[8] = rate[0] - t[9], rate[1] - t[10], rate[2] - t[11]
    for i in range(9, 15):
        out[i] = 0.0


@njit(cache=True)
def runge_kutta_points(x, T, transformed, C_b_p, f_b, v, w_ie, w_en, g, rate, lat, h, out):
    """One classical Runge-Kutta step of T s of the error dynamics at every point:
    x, out (B, P, 15); the INS's quantities at the step's start, middle and end along the
    first axis (3, B, ...): C_b_p (3, B, 3, 3), f_b, v, w_ie, w_en, g, rate (3, B, 3)
    (``_derivative``), lat, h (3, B); transformed: the ST state (else the classic one)."""
    B, P = x.shape[0], x.shape[1]
    k1, k2, k3, k4, y = (np.empty(15), np.empty(15), np.empty(15), np.empty(15),
                         np.empty(15))
    Cp, t = np.empty((3, 3)), np.empty(12)
    half, sixth = 0.5 * T, T / 6.0
    # the four stages written out: a loop over them (stage and step from tuples) ran the
    # step 15-20 % slower (paper 004's 32 episodes x 31 points)
    for b in range(B):
        for p in range(P):
            xp = x[b, p]
            _derivative(xp, transformed, C_b_p[0, b], f_b[0, b], v[0, b], w_ie[0, b],
                        w_en[0, b], g[0, b], rate[0, b], lat[0, b], h[0, b], Cp, t, k1)
            for i in range(15):
                y[i] = xp[i] + half * k1[i]
            _derivative(y, transformed, C_b_p[1, b], f_b[1, b], v[1, b], w_ie[1, b],
                        w_en[1, b], g[1, b], rate[1, b], lat[1, b], h[1, b], Cp, t, k2)
            for i in range(15):
                y[i] = xp[i] + half * k2[i]
            _derivative(y, transformed, C_b_p[1, b], f_b[1, b], v[1, b], w_ie[1, b],
                        w_en[1, b], g[1, b], rate[1, b], lat[1, b], h[1, b], Cp, t, k3)
            for i in range(15):
                y[i] = xp[i] + T * k3[i]
            _derivative(y, transformed, C_b_p[2, b], f_b[2, b], v[2, b], w_ie[2, b],
                        w_en[2, b], g[2, b], rate[2, b], lat[2, b], h[2, b], Cp, t, k4)
            for i in range(15):
                out[b, p, i] = xp[i] + sixth * (((k1[i] + 2 * k2[i]) + 2 * k3[i]) + k4[i])
