"""The strapdown mechanization compiled with Numba (``strapdown.Strapdown``): one loop
over B episodes and M IMU intervals, no Python per interval. A module of its own so that
importing the estimators does not load Numba before a mechanization runs."""
import numpy as np
from numba import njit

from aligngym.models.earth import _K_SOMIGLIANA, _M, A, E2, F, GAMMA_EQUATOR, OMEGA_IE


@njit(cache=True)
def mechanize(q0, v0, lat0, lon0, h0, a0, phi, dv_b, T, q, v, lat, lon, h, a_end):
    """The mechanization of ``Strapdown.update_compensated`` over M intervals for B
    episodes, compiled: phi, dv_b (B, M, 3); the state and the previous interval's
    acceleration a0 (B, 3) at the start; fills the trajectory q (B, M+1, 4), v (B, M+1, 3),
    lat, lon, h (B, M+1) and the last acceleration a_end (B, 3)."""
    B, M = phi.shape[0], phi.shape[1]
    for b in range(B):
        q[b, 0] = q0[b]
        v[b, 0] = v0[b]
        lat[b, 0], lon[b, 0], h[b, 0] = lat0[b], lon0[b], h0[b]
        a_e, a_nn, a_u = a0[b, 0], a0[b, 1], a0[b, 2]
        for k in range(M):
            qw, qx, qy, qz = q[b, k, 0], q[b, k, 1], q[b, k, 2], q[b, k, 3]
            ve, vn, vu = v[b, k, 0], v[b, k, 1], v[b, k, 2]
            L, hk = lat[b, k], h[b, k]
            # Mid-interval navigation quantities from the extrapolated velocity.
            me, mn, mu = ve + 0.5 * T * a_e, vn + 0.5 * T * a_nn, vu + 0.5 * T * a_u
            s0 = np.sin(L)
            R_M = A * (1.0 - E2) / (1.0 - E2 * s0 * s0) ** 1.5
            lat_mid = L + 0.5 * T * mn / (R_M + hk)
            h_mid = hk + 0.5 * T * mu
            sL, cL = np.sin(lat_mid), np.cos(lat_mid)
            w2 = 1.0 - E2 * sL * sL
            R_Mh = A * (1.0 - E2) / w2 ** 1.5 + h_mid
            R_Nh = A / np.sqrt(w2) + h_mid
            ie_n, ie_u = OMEGA_IE * cL, OMEGA_IE * sL
            en_e, en_n, en_u = -mn / R_Mh, me / R_Nh, me * sL / (cL * R_Nh)
            in_e, in_n, in_u = en_e, ie_n + en_n, ie_u + en_u
            s2 = sL * sL
            gamma = (GAMMA_EQUATOR * (1.0 + _K_SOMIGLIANA * s2) / np.sqrt(1.0 - E2 * s2)
                     * (1.0 - 2.0 / A * (1.0 + F + _M - 2.0 * F * s2) * h_mid
                        + 3.0 * h_mid * h_mid / (A * A)))
            # dv_n = C(q) dv_b, then resolved in n(k-1/2).
            bx, by, bz = dv_b[b, k, 0], dv_b[b, k, 1], dv_b[b, k, 2]
            tx, ty, tz = 2.0 * (qy * bz - qz * by), 2.0 * (qz * bx - qx * bz), \
                2.0 * (qx * by - qy * bx)
            dx = bx + qw * tx + (qy * tz - qz * ty)
            dy = by + qw * ty + (qz * tx - qx * tz)
            dz = bz + qw * tz + (qx * ty - qy * tx)
            cx, cy, cz = in_n * dz - in_u * dy, in_u * dx - in_e * dz, in_e * dy - in_n * dx
            dx, dy, dz = dx - 0.5 * T * cx, dy - 0.5 * T * cy, dz - 0.5 * T * cz
            # Coriolis and transport: (omega_ie + omega_in) x v_mid.
            we, wn, wu = in_e, ie_n + in_n, ie_u + in_u
            ce, cn, cu = wn * mu - wu * mn, wu * me - we * mu, we * mn - wn * me
            ne, nn, nu = ve + dx - T * ce, vn + dy - T * cn, vu + dz + T * (-gamma - cu)
            v[b, k + 1, 0], v[b, k + 1, 1], v[b, k + 1, 2] = ne, nn, nu
            lat[b, k + 1] = L + T * 0.5 * (vn + nn) / R_Mh
            lon[b, k + 1] = lon[b, k] + T * 0.5 * (ve + ne) / (R_Nh * cL)
            h[b, k + 1] = hk + T * 0.5 * (vu + nu)
            # q <- q(-omega_in T) q q(phi)
            px, py, pz = phi[b, k, 0], phi[b, k, 1], phi[b, k, 2]
            pw, px, py, pz = _rotvec_quat(px, py, pz)
            rw = qw * pw - qx * px - qy * py - qz * pz
            rx = qw * px + qx * pw + qy * pz - qz * py
            ry = qw * py - qx * pz + qy * pw + qz * px
            rz = qw * pz + qx * py - qy * px + qz * pw
            lw, lx, ly, lz = _rotvec_quat(-T * in_e, -T * in_n, -T * in_u)
            ow = lw * rw - lx * rx - ly * ry - lz * rz
            ox = lw * rx + lx * rw + ly * rz - lz * ry
            oy = lw * ry - lx * rz + ly * rw + lz * rx
            oz = lw * rz + lx * ry - ly * rx + lz * rw
            norm = np.sqrt(ow * ow + ox * ox + oy * oy + oz * oz)
            q[b, k + 1, 0], q[b, k + 1, 1] = ow / norm, ox / norm
            q[b, k + 1, 2], q[b, k + 1, 3] = oy / norm, oz / norm
            a_e, a_nn, a_u = (ne - ve) / T, (nn - vn) / T, (nu - vu) / T
        a_end[b, 0], a_end[b, 1], a_end[b, 2] = a_e, a_nn, a_u


@njit(cache=True)
def _rotvec_quat(x, y, z):
    """Quaternion exp of the rotation vector (x, y, z) rad."""
    angle = np.sqrt(x * x + y * y + z * z)
    half = 0.5 * angle
    scale = 0.5 - angle * angle / 48.0 if angle < 1e-4 else np.sin(half) / angle
    return np.cos(half), scale * x, scale * y, scale * z


@njit(cache=True)
def _cross(a0, a1, a2, b0, b1, b2):
    """a x b of two 3-vectors given by components (``models.attitude.cross``)."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True)
def compensate_increments(dtheta, dv, dtheta_prev0, dv_prev0, phi, dv_b):
    """``strapdown.compensate`` compiled, the arithmetic of ``coning_rotation_vector`` and
    ``body_velocity_increment`` in the same order (the same numbers): increments
    dtheta, dv (B, M, 3); the interval before the first, dtheta_prev0, dv_prev0 (B, 3);
    fills phi and dv_b (B, M, 3)."""
    for b in range(dtheta.shape[0]):
        p0, p1, p2 = dtheta_prev0[b, 0], dtheta_prev0[b, 1], dtheta_prev0[b, 2]
        q0, q1, q2 = dv_prev0[b, 0], dv_prev0[b, 1], dv_prev0[b, 2]
        for k in range(dtheta.shape[1]):
            t0, t1, t2 = dtheta[b, k, 0], dtheta[b, k, 1], dtheta[b, k, 2]
            v0, v1, v2 = dv[b, k, 0], dv[b, k, 1], dv[b, k, 2]
            x0, x1, x2 = _cross(p0, p1, p2, t0, t1, t2)
            phi[b, k, 0], phi[b, k, 1], phi[b, k, 2] = t0 + x0 / 12.0, t1 + x1 / 12.0, \
                t2 + x2 / 12.0
            a0, a1, a2 = 0.5 * (t0 + p0), 0.5 * (t1 + p1), 0.5 * (t2 + p2)
            e0, e1, e2 = 0.5 * (t0 - p0), 0.5 * (t1 - p1), 0.5 * (t2 - p2)
            c0, c1, c2 = 0.5 * (v0 + q0), 0.5 * (v1 + q1), 0.5 * (v2 + q2)
            d0, d1, d2 = v0 - q0, v1 - q1, v2 - q2
            ac = _cross(a0, a1, a2, c0, c1, c2)
            ad = _cross(a0, a1, a2, d0, d1, d2)
            ec = _cross(e0, e1, e2, c0, c1, c2)
            ed = _cross(e0, e1, e2, d0, d1, d2)
            a_ac = _cross(a0, a1, a2, ac[0], ac[1], ac[2])
            a_ad = _cross(a0, a1, a2, ad[0], ad[1], ad[2])
            a_ec = _cross(a0, a1, a2, ec[0], ec[1], ec[2])
            e_ac = _cross(e0, e1, e2, ac[0], ac[1], ac[2])
            a_ed = _cross(a0, a1, a2, ed[0], ed[1], ed[2])
            e_ad = _cross(e0, e1, e2, ad[0], ad[1], ad[2])
            e_ec = _cross(e0, e1, e2, ec[0], ec[1], ec[2])
            e_ed = _cross(e0, e1, e2, ed[0], ed[1], ed[2])
            ae = _cross(a0, a1, a2, e0, e1, e2)
            w = (c0 / 24.0 + d0 / 30.0, c1 / 24.0 + d1 / 30.0, c2 / 24.0 + d2 / 30.0)
            coning = _cross(ae[0], ae[1], ae[2], w[0], w[1], w[2])
            vel = (v0, v1, v2)
            for i in range(3):
                first = ac[i] / 2.0 + ad[i] / 3.0 + ec[i] / 3.0 + ed[i] / 4.0
                second = 0.5 * (a_ac[i] / 3.0 + a_ad[i] / 4.0 + (a_ec[i] + e_ac[i]) / 4.0
                                 + (a_ed[i] + e_ad[i]) / 5.0 + e_ec[i] / 5.0
                                 + e_ed[i] / 6.0)
                dv_b[b, k, i] = vel[i] + first + second + coning[i]
            p0, p1, p2, q0, q1, q2 = t0, t1, t2, v0, v1, v2
