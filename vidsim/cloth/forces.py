"""Cloth forces (Numba kernels): Baraff-Witkin stretch/shear/bend, damping, drag, gravity.

Every kernel *adds* its forces into ``f`` (N, 3) [N] and returns its energy [J] (for the
conservative forces) so that gradients can be checked against finite differences.

Conditions (seed eq. 8-10, Baraff & Witkin 1998), with energies linear in rest area a:

* stretch: C_u = sqrt(a) (|w_u| - 1), C_v = sqrt(a) (|w_v| - 1);  E = k_s/2 (C_u^2 + C_v^2)
* shear:   C = sqrt(a) w_u . w_v;                                E = k_sh/2 C^2
* bend:    C = sqrt(c_e) (theta - theta_0), c_e = |e|^2/(A_1+A_2); E = k_b/2 C^2

where w_u, w_v are the deformation gradient columns (d x / d u, d x / d v) and theta is
the dihedral angle across an interior edge. Damping per condition is
d = -k_d (dC/dx) dC/dt. Drag per triangle (seed section 4.2):
f = -a' (k_N |v_N|^2 / (1 + k_f |v_N|^2) v_N/|v_N| + k_T v_T), with a' the triangle's
*current* (deformed) area (not the rest area a of the conditions), v the face's mean velocity
relative to the air (``wind``), split into normal and tangential parts, shared equally by the
three corners.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "stretch_shear_forces",
    "bend_forces",
    "bend_forces_quadratic",
    "atan2_fast",
    "drag_forces",
    "gravity_forces",
    "dihedral_angles",
    "drag_dissipation_potential",
]


# Cephes atan: argument reduced to |t| <= tan(pi/8), then t + t^3 P(t^2)/Q(t^2)
_AP0 = -8.750608600031904122785e-1
_AP1 = -1.615753718733365076637e1
_AP2 = -7.500855792314704667340e1
_AP3 = -1.228866684490136173410e2
_AP4 = -6.485021904942025371773e1
_AQ0 = 2.485846490142306297962e1
_AQ1 = 1.650270098316988542046e2
_AQ2 = 4.328810604912902668951e2
_AQ3 = 4.853903996359136964868e2
_AQ4 = 1.945506571482613964425e2
_MOREBITS = 6.123233995736765886130e-17


@njit(cache=True, inline="always")
def atan2_fast(y: float, x: float) -> float:
    """atan2(y, x) [rad] inlined into the kernels (Cephes' rational atan, within 5e-16 of
    ``math.atan2``; tested). The libm call cost 16 ns of the bend kernel's 54 ns per edge."""
    ay = abs(y)
    ax = abs(x)
    swap = ay > ax
    if swap:
        t = ax / ay
    elif ax > 0.0:
        t = ay / ax
    else:
        t = 0.0
    base = 0.0
    more = 0.0
    if t > 0.41421356237309504880:  # tan(pi/8): reduce with atan(t) = pi/4 + atan((t-1)/(t+1))
        base = 0.78539816339744830962
        more = 0.5 * _MOREBITS
        t = (t - 1.0) / (t + 1.0)
    z = t * t
    pz = (((_AP0 * z + _AP1) * z + _AP2) * z + _AP3) * z + _AP4
    qz = ((((z + _AQ0) * z + _AQ1) * z + _AQ2) * z + _AQ3) * z + _AQ4
    r = base + (t * z * pz / qz + t + more)
    if swap:
        r = 1.57079632679489661923 - r
    if x < 0.0:
        r = 3.14159265358979323846 - r
    if y < 0.0:
        r = -r
    return r


@njit(cache=True, fastmath=True)
def stretch_shear_forces(
    x: np.ndarray,
    v: np.ndarray,
    tris: np.ndarray,
    coef: np.ndarray,
    area: np.ndarray,
    k_stretch: float,
    k_stretch_v: float,
    k_shear: float,
    kd_stretch: float,
    kd_shear: float,
    f: np.ndarray,
) -> tuple[float, float]:
    """Add Baraff-Witkin stretch and shear forces (elastic + damping) to ``f``.

    Args:
        x: (N, 3) positions [m]. v: (N, 3) velocities [m/s].
        tris: (M, 3) int. coef: (M, 6) dw_u/dx_{ijk}, dw_v/dx_{ijk} [1/m].
        area: (M,) rest areas [m^2].
        k_stretch: stretch stiffness along the warp (u) [N/m]; k_stretch_v: along the weft (v)
            (equal for an isotropic fabric, see ``ClothParams.stretch_anisotropy``).
        k_shear: [N/m]. kd_stretch, kd_shear: [N s/m].
        f: (N, 3) force accumulator [N], modified in place.

    Returns:
        (stretch energy, shear energy) [J].
    """
    e_st = 0.0
    e_sh = 0.0
    for t in range(tris.shape[0]):
        i = tris[t, 0]
        j = tris[t, 1]
        k = tris[t, 2]
        ai = coef[t, 0]
        aj = coef[t, 1]
        ak = coef[t, 2]
        bi = coef[t, 3]
        bj = coef[t, 4]
        bk = coef[t, 5]
        A = area[t]
        wu0 = ai * x[i, 0] + aj * x[j, 0] + ak * x[k, 0]
        wu1 = ai * x[i, 1] + aj * x[j, 1] + ak * x[k, 1]
        wu2 = ai * x[i, 2] + aj * x[j, 2] + ak * x[k, 2]
        wv0 = bi * x[i, 0] + bj * x[j, 0] + bk * x[k, 0]
        wv1 = bi * x[i, 1] + bj * x[j, 1] + bk * x[k, 1]
        wv2 = bi * x[i, 2] + bj * x[j, 2] + bk * x[k, 2]
        du0 = ai * v[i, 0] + aj * v[j, 0] + ak * v[k, 0]
        du1 = ai * v[i, 1] + aj * v[j, 1] + ak * v[k, 1]
        du2 = ai * v[i, 2] + aj * v[j, 2] + ak * v[k, 2]
        dv0 = bi * v[i, 0] + bj * v[j, 0] + bk * v[k, 0]
        dv1 = bi * v[i, 1] + bj * v[j, 1] + bk * v[k, 1]
        dv2 = bi * v[i, 2] + bj * v[j, 2] + bk * v[k, 2]
        lu = math.sqrt(wu0 * wu0 + wu1 * wu1 + wu2 * wu2)
        lv = math.sqrt(wv0 * wv0 + wv1 * wv1 + wv2 * wv2)
        if lu < 1e-12 or lv < 1e-12:
            continue
        iu = 1.0 / lu
        iv = 1.0 / lv
        cu = lu - 1.0
        cv = lv - 1.0
        cud = (wu0 * du0 + wu1 * du1 + wu2 * du2) * iu
        cvd = (wv0 * dv0 + wv1 * dv1 + wv2 * dv2) * iv
        if k_stretch_v == k_stretch:
            e_st += 0.5 * k_stretch * A * (cu * cu + cv * cv)
        else:
            e_st += 0.5 * A * (k_stretch * cu * cu + k_stretch_v * cv * cv)
        su = A * (k_stretch * cu + kd_stretch * cud) * iu  # times w_u (not unit) below
        sv = A * (k_stretch_v * cv + kd_stretch * cvd) * iv
        csh = wu0 * wv0 + wu1 * wv1 + wu2 * wv2
        cshd = du0 * wv0 + du1 * wv1 + du2 * wv2 + wu0 * dv0 + wu1 * dv1 + wu2 * dv2
        e_sh += 0.5 * k_shear * A * csh * csh
        ss = A * (k_shear * csh + kd_shear * cshd)
        # dE/dx_m = su * a_m * w_u + sv * b_m * w_v + ss * (a_m * w_v + b_m * w_u)
        gu = su
        gv = sv
        # vector terms: P = gu*w_u + ss*w_v (multiplies a_m), Q = gv*w_v + ss*w_u (multiplies b_m)
        p0 = gu * wu0 + ss * wv0
        p1 = gu * wu1 + ss * wv1
        p2 = gu * wu2 + ss * wv2
        q0 = gv * wv0 + ss * wu0
        q1 = gv * wv1 + ss * wu1
        q2 = gv * wv2 + ss * wu2
        f[i, 0] -= ai * p0 + bi * q0
        f[i, 1] -= ai * p1 + bi * q1
        f[i, 2] -= ai * p2 + bi * q2
        f[j, 0] -= aj * p0 + bj * q0
        f[j, 1] -= aj * p1 + bj * q1
        f[j, 2] -= aj * p2 + bj * q2
        f[k, 0] -= ak * p0 + bk * q0
        f[k, 1] -= ak * p1 + bk * q1
        f[k, 2] -= ak * p2 + bk * q2
    return e_st, e_sh


@njit(cache=True, fastmath=True)
def bend_forces(
    x: np.ndarray,
    v: np.ndarray,
    edges: np.ndarray,
    bcoef: np.ndarray,
    brest: np.ndarray,
    k_bend: float,
    kd_bend: float,
    f: np.ndarray,
) -> float:
    """Add dihedral-angle bending forces (elastic + damping) to ``f``.

    Args:
        x, v: (N, 3) positions [m] and velocities [m/s].
        edges: (E, 4) int (x0, x1, x2, x3), see :class:`~vidsim.cloth.mesh.ClothMesh`.
        bcoef: (E,) |e|^2/(A1+A2) at rest. brest: (E,) rest angles [rad].
        k_bend: bending rigidity [N m]. kd_bend: [N m s].
        f: (N, 3) accumulator [N].

    Returns:
        Bending energy [J].
    """
    energy = 0.0
    for q in range(edges.shape[0]):
        i0 = edges[q, 0]
        i1 = edges[q, 1]
        i2 = edges[q, 2]
        i3 = edges[q, 3]
        e0 = x[i1, 0] - x[i0, 0]
        e1 = x[i1, 1] - x[i0, 1]
        e2 = x[i1, 2] - x[i0, 2]
        a0 = x[i2, 0] - x[i0, 0]
        a1 = x[i2, 1] - x[i0, 1]
        a2 = x[i2, 2] - x[i0, 2]
        b0 = x[i3, 0] - x[i1, 0]
        b1 = x[i3, 1] - x[i1, 1]
        b2 = x[i3, 2] - x[i1, 2]
        # n1 = e x a ; n2 = (-e) x b
        n10 = e1 * a2 - e2 * a1
        n11 = e2 * a0 - e0 * a2
        n12 = e0 * a1 - e1 * a0
        n20 = -(e1 * b2 - e2 * b1)
        n21 = -(e2 * b0 - e0 * b2)
        n22 = -(e0 * b1 - e1 * b0)
        el2 = e0 * e0 + e1 * e1 + e2 * e2
        nn1 = n10 * n10 + n11 * n11 + n12 * n12
        nn2 = n20 * n20 + n21 * n21 + n22 * n22
        if el2 < 1e-24 or nn1 < 1e-30 or nn2 < 1e-30:
            continue
        el = math.sqrt(el2)
        c0 = n11 * n22 - n12 * n21
        c1 = n12 * n20 - n10 * n22
        c2 = n10 * n21 - n11 * n20
        sn = (c0 * e0 + c1 * e1 + c2 * e2) / el
        cs = n10 * n20 + n11 * n21 + n12 * n22
        theta = atan2_fast(sn, cs)
        # gradient of theta
        inv1 = 1.0 / nn1
        inv2 = 1.0 / nn2
        m10 = n10 * inv1
        m11 = n11 * inv1
        m12 = n12 * inv1
        m20 = n20 * inv2
        m21 = n21 * inv2
        m22 = n22 * inv2
        ie = 1.0 / el
        # projections on the unit edge
        d20 = (a0 * e0 + a1 * e1 + a2 * e2) * ie  # (x2-x0).e^
        d21 = el - d20  # (x1-x2).e^
        d30 = (b0 * e0 + b1 * e1 + b2 * e2) * ie + el  # (x3-x0).e^
        d31 = el - d30  # (x1-x3).e^
        g20 = -el * m10
        g21 = -el * m11
        g22 = -el * m12
        g30 = -el * m20
        g31 = -el * m21
        g32 = -el * m22
        g00 = d21 * m10 + d31 * m20
        g01 = d21 * m11 + d31 * m21
        g02 = d21 * m12 + d31 * m22
        g10 = d20 * m10 + d30 * m20
        g11 = d20 * m11 + d30 * m21
        g12 = d20 * m12 + d30 * m22
        thd = (
            g00 * v[i0, 0] + g01 * v[i0, 1] + g02 * v[i0, 2]
            + g10 * v[i1, 0] + g11 * v[i1, 1] + g12 * v[i1, 2]
            + g20 * v[i2, 0] + g21 * v[i2, 1] + g22 * v[i2, 2]
            + g30 * v[i3, 0] + g31 * v[i3, 1] + g32 * v[i3, 2]
        )
        dth = theta - brest[q]
        c = bcoef[q]
        energy += 0.5 * k_bend * c * dth * dth
        s = c * (k_bend * dth + kd_bend * thd)
        f[i0, 0] -= s * g00
        f[i0, 1] -= s * g01
        f[i0, 2] -= s * g02
        f[i1, 0] -= s * g10
        f[i1, 1] -= s * g11
        f[i1, 2] -= s * g12
        f[i2, 0] -= s * g20
        f[i2, 1] -= s * g21
        f[i2, 2] -= s * g22
        f[i3, 0] -= s * g30
        f[i3, 1] -= s * g31
        f[i3, 2] -= s * g32
    return energy


@njit(cache=True, fastmath=True)
def drag_forces(
    x: np.ndarray,
    v: np.ndarray,
    tris: np.ndarray,
    k_t: float,
    k_n: float,
    k_f: float,
    wind: np.ndarray,
    f: np.ndarray,
) -> None:
    """Add the seed's nonlinear air drag per triangle (current area) to ``f``.

    Args:
        x, v: (N, 3) [m], [m/s]. tris: (M, 3) int.
        k_t: tangential linear drag [N s/m^3]. k_n: normal quadratic drag [kg/m^3].
        k_f: degradation [s^2/m^2]. wind: (3,) air velocity [m/s] (uniform).
        f: (N, 3) accumulator [N].
    """
    if k_t == 0.0 and k_n == 0.0:
        return
    third = 1.0 / 3.0
    for t in range(tris.shape[0]):
        i = tris[t, 0]
        j = tris[t, 1]
        k = tris[t, 2]
        p0 = x[j, 0] - x[i, 0]
        p1 = x[j, 1] - x[i, 1]
        p2 = x[j, 2] - x[i, 2]
        q0 = x[k, 0] - x[i, 0]
        q1 = x[k, 1] - x[i, 1]
        q2 = x[k, 2] - x[i, 2]
        n0 = p1 * q2 - p2 * q1
        n1 = p2 * q0 - p0 * q2
        n2 = p0 * q1 - p1 * q0
        nl = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        if nl < 1e-30:
            continue
        A = 0.5 * nl
        n0 /= nl
        n1 /= nl
        n2 /= nl
        r0 = (v[i, 0] + v[j, 0] + v[k, 0]) * third - wind[0]
        r1 = (v[i, 1] + v[j, 1] + v[k, 1]) * third - wind[1]
        r2 = (v[i, 2] + v[j, 2] + v[k, 2]) * third - wind[2]
        vn = r0 * n0 + r1 * n1 + r2 * n2
        t0 = r0 - vn * n0
        t1 = r1 - vn * n1
        t2 = r2 - vn * n2
        # kN |vN|^2/(1+kf|vN|^2) * vN/|vN| = kN |vn| vn/(1+kf vn^2) * n
        fn = k_n * abs(vn) * vn / (1.0 + k_f * vn * vn)
        s = -A * third
        f0 = s * (fn * n0 + k_t * t0)
        f1 = s * (fn * n1 + k_t * t1)
        f2 = s * (fn * n2 + k_t * t2)
        f[i, 0] += f0
        f[i, 1] += f1
        f[i, 2] += f2
        f[j, 0] += f0
        f[j, 1] += f1
        f[j, 2] += f2
        f[k, 0] += f0
        f[k, 1] += f1
        f[k, 2] += f2


@njit(cache=True)
def gravity_forces(x: np.ndarray, mass: np.ndarray, g: np.ndarray, f: np.ndarray) -> float:
    """Add m g to ``f``; return the gravitational potential energy -sum m g.x [J]."""
    e = 0.0
    for i in range(x.shape[0]):
        f[i, 0] += mass[i] * g[0]
        f[i, 1] += mass[i] * g[1]
        f[i, 2] += mass[i] * g[2]
        e -= mass[i] * (g[0] * x[i, 0] + g[1] * x[i, 1] + g[2] * x[i, 2])
    return e


def dihedral_angles(x: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Dihedral angles [rad], shape (E,), same convention as :func:`bend_forces`."""
    x0, x1, x2, x3 = (x[edges[:, c]] for c in range(4))
    e = x1 - x0
    n1 = np.cross(e, x2 - x0)
    n2 = np.cross(-e, x3 - x1)
    en = e / np.linalg.norm(e, axis=1, keepdims=True)
    return np.arctan2(np.einsum("ij,ij->i", np.cross(n1, n2), en), np.einsum("ij,ij->i", n1, n2))


def drag_dissipation_potential(
    x: np.ndarray, v: np.ndarray, tris: np.ndarray, k_t: float, k_n: float, k_f: float, wind: np.ndarray
) -> float:
    """Dissipation potential Phi(v) [W] whose negative velocity gradient is the drag force.

    Phi = sum_t a_t (k_T/2 |v_T|^2 + k_N * I(|v_N|)), I(s) = int_0^s r^2/(1 + k_f r^2) dr,
    at fixed positions. Used to check :func:`drag_forces` by finite differences.
    """
    P = x[tris]
    n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    nl = np.linalg.norm(n, axis=1)
    A = 0.5 * nl
    nh = n / nl[:, None]
    r = v[tris].mean(axis=1) - wind[None, :]
    vn = np.einsum("ij,ij->i", r, nh)
    vt = r - vn[:, None] * nh
    s = np.abs(vn)
    if k_f > 0:
        integ = s / k_f - np.arctan(math.sqrt(k_f) * s) / k_f**1.5
    else:
        integ = s**3 / 3.0
    return float(np.sum(A * (0.5 * k_t * np.einsum("ij,ij->i", vt, vt) + k_n * integ)))


@njit(cache=True, fastmath=True)
def triangle_forces(
    x: np.ndarray,
    v: np.ndarray,
    tris: np.ndarray,
    coef: np.ndarray,
    area: np.ndarray,
    k_stretch: float,
    k_stretch_v: float,
    k_shear: float,
    kd_stretch: float,
    kd_shear: float,
    k_t: float,
    k_n: float,
    k_f: float,
    wind: np.ndarray,
    tnorm: np.ndarray,
    f: np.ndarray,
) -> None:
    """Fused per-triangle kernel: stretch + shear (+ damping) + drag, and the triangles'
    area-weighted normals (M, 3) into ``tnorm`` for :func:`bend_forces_fused`.

    Same forces as :func:`stretch_shear_forces` plus :func:`drag_forces` (one pass over
    memory instead of two). Units as there (``k_stretch`` warp, ``k_stretch_v`` weft).
    """
    third = 1.0 / 3.0
    sixth = 1.0 / 6.0
    drag = k_t != 0.0 or k_n != 0.0
    for t in range(tris.shape[0]):
        i = tris[t, 0]
        j = tris[t, 1]
        k = tris[t, 2]
        xi0 = x[i, 0]; xi1 = x[i, 1]; xi2 = x[i, 2]
        xj0 = x[j, 0]; xj1 = x[j, 1]; xj2 = x[j, 2]
        xk0 = x[k, 0]; xk1 = x[k, 1]; xk2 = x[k, 2]
        vi0 = v[i, 0]; vi1 = v[i, 1]; vi2 = v[i, 2]
        vj0 = v[j, 0]; vj1 = v[j, 1]; vj2 = v[j, 2]
        vk0 = v[k, 0]; vk1 = v[k, 1]; vk2 = v[k, 2]
        ai = coef[t, 0]; aj = coef[t, 1]; ak = coef[t, 2]
        bi = coef[t, 3]; bj = coef[t, 4]; bk = coef[t, 5]
        A = area[t]
        wu0 = ai * xi0 + aj * xj0 + ak * xk0
        wu1 = ai * xi1 + aj * xj1 + ak * xk1
        wu2 = ai * xi2 + aj * xj2 + ak * xk2
        wv0 = bi * xi0 + bj * xj0 + bk * xk0
        wv1 = bi * xi1 + bj * xj1 + bk * xk1
        wv2 = bi * xi2 + bj * xj2 + bk * xk2
        du0 = ai * vi0 + aj * vj0 + ak * vk0
        du1 = ai * vi1 + aj * vj1 + ak * vk1
        du2 = ai * vi2 + aj * vj2 + ak * vk2
        dv0 = bi * vi0 + bj * vj0 + bk * vk0
        dv1 = bi * vi1 + bj * vj1 + bk * vk1
        dv2 = bi * vi2 + bj * vj2 + bk * vk2
        # normal (area weighted) of the current triangle
        p0 = xj0 - xi0; p1 = xj1 - xi1; p2 = xj2 - xi2
        q0 = xk0 - xi0; q1 = xk1 - xi1; q2 = xk2 - xi2
        n0 = p1 * q2 - p2 * q1
        n1 = p2 * q0 - p0 * q2
        n2 = p0 * q1 - p1 * q0
        tnorm[t, 0] = n0
        tnorm[t, 1] = n1
        tnorm[t, 2] = n2
        lu2 = wu0 * wu0 + wu1 * wu1 + wu2 * wu2
        lv2 = wv0 * wv0 + wv1 * wv1 + wv2 * wv2
        fi0 = 0.0; fi1 = 0.0; fi2 = 0.0
        fj0 = 0.0; fj1 = 0.0; fj2 = 0.0
        fk0 = 0.0; fk1 = 0.0; fk2 = 0.0
        if lu2 > 1e-24 and lv2 > 1e-24:
            # one division for both inverse lengths (the sqrt/div units bound this loop)
            lu = math.sqrt(lu2)
            lv = math.sqrt(lv2)
            inv = 1.0 / (lu * lv)
            iu = lv * inv
            iv = lu * inv
            cu = lu - 1.0
            cv = lv - 1.0
            cud = (wu0 * du0 + wu1 * du1 + wu2 * du2) * iu
            cvd = (wv0 * dv0 + wv1 * dv1 + wv2 * dv2) * iv
            su = A * (k_stretch * cu + kd_stretch * cud) * iu
            sv = A * (k_stretch_v * cv + kd_stretch * cvd) * iv
            csh = wu0 * wv0 + wu1 * wv1 + wu2 * wv2
            cshd = du0 * wv0 + du1 * wv1 + du2 * wv2 + wu0 * dv0 + wu1 * dv1 + wu2 * dv2
            ss = A * (k_shear * csh + kd_shear * cshd)
            P0 = su * wu0 + ss * wv0
            P1 = su * wu1 + ss * wv1
            P2 = su * wu2 + ss * wv2
            Q0 = sv * wv0 + ss * wu0
            Q1 = sv * wv1 + ss * wu1
            Q2 = sv * wv2 + ss * wu2
            fi0 = -(ai * P0 + bi * Q0); fi1 = -(ai * P1 + bi * Q1); fi2 = -(ai * P2 + bi * Q2)
            fj0 = -(aj * P0 + bj * Q0); fj1 = -(aj * P1 + bj * Q1); fj2 = -(aj * P2 + bj * Q2)
            fk0 = -(ak * P0 + bk * Q0); fk1 = -(ak * P1 + bk * Q1); fk2 = -(ak * P2 + bk * Q2)
        if drag:
            nn = n0 * n0 + n1 * n1 + n2 * n2
            if nn > 1e-60:
                nl = math.sqrt(nn)
                r0 = (vi0 + vj0 + vk0) * third - wind[0]
                r1 = (vi1 + vj1 + vk1) * third - wind[1]
                r2 = (vi2 + vj2 + vk2) * third - wind[2]
                # with the unnormalised normal n (|n| = nl = 2a) and rn = r.n = vN nl:
                # f_corner = -(a/3) (kN |vN| vN/(1 + kf vN^2) n/nl + kT (r - vN n/nl))
                #          = -(1/6) (kN |rn| rn nl/(nl den) n + kT (nl r - rn den/(nl den) n)),
                # den = nl^2 + kf rn^2: one division instead of two
                rn = r0 * n0 + r1 * n1 + r2 * n2
                den = nn + k_f * rn * rn
                inv = 1.0 / (nl * den)
                cn = (k_n * abs(rn) * rn * nl - k_t * rn * den) * inv
                ktl = k_t * nl
                g0 = -sixth * (cn * n0 + ktl * r0)
                g1 = -sixth * (cn * n1 + ktl * r1)
                g2 = -sixth * (cn * n2 + ktl * r2)
                fi0 += g0; fi1 += g1; fi2 += g2
                fj0 += g0; fj1 += g1; fj2 += g2
                fk0 += g0; fk1 += g1; fk2 += g2
        f[i, 0] += fi0; f[i, 1] += fi1; f[i, 2] += fi2
        f[j, 0] += fj0; f[j, 1] += fj1; f[j, 2] += fj2
        f[k, 0] += fk0; f[k, 1] += fk1; f[k, 2] += fk2


@njit(cache=True, fastmath=True)
def bend_forces_fused(
    x: np.ndarray,
    v: np.ndarray,
    edges: np.ndarray,
    etris: np.ndarray,
    tnorm: np.ndarray,
    bcoef: np.ndarray,
    brest: np.ndarray,
    k_bend: float,
    kd_bend: float,
    f: np.ndarray,
) -> None:
    """:func:`bend_forces` reusing the triangle normals from :func:`triangle_forces`.

    Args:
        etris: (E, 2) the two triangles of each bend edge (first is (x0, x1, x2)).
        tnorm: (M, 3) area-weighted triangle normals in each triangle's winding.
    """
    if k_bend == 0.0 and kd_bend == 0.0:
        return
    for q in range(edges.shape[0]):
        i0 = edges[q, 0]
        i1 = edges[q, 1]
        i2 = edges[q, 2]
        i3 = edges[q, 3]
        t1 = etris[q, 0]
        t2 = etris[q, 1]
        n10 = tnorm[t1, 0]; n11 = tnorm[t1, 1]; n12 = tnorm[t1, 2]
        n20 = tnorm[t2, 0]; n21 = tnorm[t2, 1]; n22 = tnorm[t2, 2]
        x00 = x[i0, 0]; x01 = x[i0, 1]; x02 = x[i0, 2]
        e0 = x[i1, 0] - x00
        e1 = x[i1, 1] - x01
        e2 = x[i1, 2] - x02
        el2 = e0 * e0 + e1 * e1 + e2 * e2
        nn1 = n10 * n10 + n11 * n11 + n12 * n12
        nn2 = n20 * n20 + n21 * n21 + n22 * n22
        if el2 < 1e-24 or nn1 < 1e-30 or nn2 < 1e-30:
            continue
        el = math.sqrt(el2)
        ie = 1.0 / el
        c0 = n11 * n22 - n12 * n21
        c1 = n12 * n20 - n10 * n22
        c2 = n10 * n21 - n11 * n20
        sn = (c0 * e0 + c1 * e1 + c2 * e2) * ie
        cs = n10 * n20 + n11 * n21 + n12 * n22
        theta = atan2_fast(sn, cs)
        inv1 = 1.0 / nn1
        inv2 = 1.0 / nn2
        m10 = n10 * inv1; m11 = n11 * inv1; m12 = n12 * inv1
        m20 = n20 * inv2; m21 = n21 * inv2; m22 = n22 * inv2
        d20 = ((x[i2, 0] - x00) * e0 + (x[i2, 1] - x01) * e1 + (x[i2, 2] - x02) * e2) * ie
        d21 = el - d20
        d30 = ((x[i3, 0] - x00) * e0 + (x[i3, 1] - x01) * e1 + (x[i3, 2] - x02) * e2) * ie
        d31 = el - d30
        g20 = -el * m10; g21 = -el * m11; g22 = -el * m12
        g30 = -el * m20; g31 = -el * m21; g32 = -el * m22
        g00 = d21 * m10 + d31 * m20
        g01 = d21 * m11 + d31 * m21
        g02 = d21 * m12 + d31 * m22
        g10 = d20 * m10 + d30 * m20
        g11 = d20 * m11 + d30 * m21
        g12 = d20 * m12 + d30 * m22
        thd = 0.0
        if kd_bend != 0.0:
            thd = (
                g00 * v[i0, 0] + g01 * v[i0, 1] + g02 * v[i0, 2]
                + g10 * v[i1, 0] + g11 * v[i1, 1] + g12 * v[i1, 2]
                + g20 * v[i2, 0] + g21 * v[i2, 1] + g22 * v[i2, 2]
                + g30 * v[i3, 0] + g31 * v[i3, 1] + g32 * v[i3, 2]
            )
        s = bcoef[q] * (k_bend * (theta - brest[q]) + kd_bend * thd)
        f[i0, 0] -= s * g00; f[i0, 1] -= s * g01; f[i0, 2] -= s * g02
        f[i1, 0] -= s * g10; f[i1, 1] -= s * g11; f[i1, 2] -= s * g12
        f[i2, 0] -= s * g20; f[i2, 1] -= s * g21; f[i2, 2] -= s * g22
        f[i3, 0] -= s * g30; f[i3, 1] -= s * g31; f[i3, 2] -= s * g32


@njit(cache=True, fastmath=True)
def bend_forces_quadratic(
    x: np.ndarray,
    v: np.ndarray,
    edges: np.ndarray,
    qk: np.ndarray,
    k_bend: float,
    kd_bend: float,
    f: np.ndarray,
    project_damping: bool = True,
) -> float:
    """Add the quadratic (isometric) bending forces of Bergou et al. 2006 to ``f``.

    Per interior edge, w = sum_j K_j x_j over its four vertices (x0, x1, x2, x3) with the
    rest cotangent weights K scaled by 1/sqrt(A1 + A2) (``ClothMesh.bend_quad``), and
    E = k_b/2 |w|^2. For a flat rest shape and small dihedral angles theta this equals the
    dihedral energy k_b/2 |e|^2/(A1+A2) theta^2 of :func:`bend_forces` (|w| = |e| theta /
    sqrt(A1 + A2)), so ``bend`` keeps its meaning (D [N m]); at large angles
    |w| = 2|e| sin(theta/2) / sqrt(A1 + A2) for a
    hinge fold (softer: 0.81x the energy at 90 degrees). The Hessian is constant, so the
    elastic forces are linear in x: no sqrt, division or atan.

    Damping (seed eq. 10 with the scalar condition C = |w|, like BW's C ~ theta):
    d_j = -kd K_j w (w . w_dot) / (|w|^2 + 1e-18), w_dot = sum_i K_i v_i, the negative
    velocity gradient of R = kd/2 (w . w_dot)^2 / |w|^2. It vanishes for rigid motions, so
    it conserves linear and angular momentum (the plain -kd K_j w_dot resists the rigid
    rotation of a bent sheet). ``project_damping=False`` gives that plain form, whose rate
    bounds the projected one from above; :func:`vidsim.cloth.stable_step` uses it.

    Args:
        x, v: (N, 3) [m], [m/s]. edges: (E, 4) int. qk: (E, 4) weights [1/m].
        k_bend: [N m]. kd_bend: [N m s]. f: (N, 3) accumulator [N].

    Returns:
        Bending energy [J].
    """
    energy = 0.0
    if k_bend == 0.0 and kd_bend == 0.0:
        return energy
    for q in range(edges.shape[0]):
        i0 = edges[q, 0]
        i1 = edges[q, 1]
        i2 = edges[q, 2]
        i3 = edges[q, 3]
        k0 = qk[q, 0]; k1 = qk[q, 1]; k2 = qk[q, 2]; k3 = qk[q, 3]
        w0 = k0 * x[i0, 0] + k1 * x[i1, 0] + k2 * x[i2, 0] + k3 * x[i3, 0]
        w1 = k0 * x[i0, 1] + k1 * x[i1, 1] + k2 * x[i2, 1] + k3 * x[i3, 1]
        w2 = k0 * x[i0, 2] + k1 * x[i1, 2] + k2 * x[i2, 2] + k3 * x[i3, 2]
        energy += 0.5 * k_bend * (w0 * w0 + w1 * w1 + w2 * w2)
        u0 = k_bend * w0
        u1 = k_bend * w1
        u2 = k_bend * w2
        if kd_bend != 0.0:
            z0 = k0 * v[i0, 0] + k1 * v[i1, 0] + k2 * v[i2, 0] + k3 * v[i3, 0]
            z1 = k0 * v[i0, 1] + k1 * v[i1, 1] + k2 * v[i2, 1] + k3 * v[i3, 1]
            z2 = k0 * v[i0, 2] + k1 * v[i1, 2] + k2 * v[i2, 2] + k3 * v[i3, 2]
            if project_damping:
                sd = kd_bend * (w0 * z0 + w1 * z1 + w2 * z2) / (w0 * w0 + w1 * w1 + w2 * w2 + 1e-18)
                u0 += sd * w0
                u1 += sd * w1
                u2 += sd * w2
            else:
                u0 += kd_bend * z0
                u1 += kd_bend * z1
                u2 += kd_bend * z2
        f[i0, 0] -= k0 * u0; f[i0, 1] -= k0 * u1; f[i0, 2] -= k0 * u2
        f[i1, 0] -= k1 * u0; f[i1, 1] -= k1 * u1; f[i1, 2] -= k1 * u2
        f[i2, 0] -= k2 * u0; f[i2, 1] -= k2 * u1; f[i2, 2] -= k2 * u2
        f[i3, 0] -= k3 * u0; f[i3, 1] -= k3 * u1; f[i3, 2] -= k3 * u2
    return energy


@njit(cache=True, fastmath=True)
def _decay(cdot: float, c: float, wsum: float) -> float:
    """The multiplier lambda of M^-1 J^T that takes one condition's rate ``cdot`` to ``cdot R(x)``,
    x = c w the condition's decay over the step (c = k_d h, w = J M^-1 J^T).

    R(x) = 1 / (1 + x + x^2/2), the (0, 2) Pade approximant of exp(-x): second-order accurate, in (0, 1]
    for every x >= 0 (L-stable: a stiff condition's rate is removed, never reversed), one division
    and no exp (a libm exp per condition cost more than the step's force evaluation). Then
    lambda = cdot (R - 1) / w = -cdot c (1 + x/2) R, finite at w = 0.
    """
    x = c * wsum
    return -cdot * c * (1.0 + 0.5 * x) / (1.0 + x * (1.0 + 0.5 * x))


@njit(cache=True, fastmath=True)
def damping_sweep(
    x: np.ndarray,
    v: np.ndarray,
    tris: np.ndarray,
    coef: np.ndarray,
    area: np.ndarray,
    kd_stretch: float,
    kd_shear: float,
    edges: np.ndarray,
    etris: np.ndarray,
    tnorm: np.ndarray,
    bcoef: np.ndarray,
    bquad: np.ndarray,
    quad: bool,
    kd_bend: float,
    im: np.ndarray,
    h: float,
) -> None:
    """Apply the Baraff-Witkin condition dampings over a step ``h`` [s] to the velocities ``v`` in place,
    one condition at a time (the "split" damping of :func:`vidsim.cloth.simulate`).

    Each condition C (stretch C_u, C_v and shear C of every triangle; the bending condition of every
    interior edge) has the damping force d = -k_d J^T dC/dt, J = dC/dx, at fixed x; alone it is the
    linear ODE M dv/dt = -k_d J^T J v, which takes dC/dt = J v to dC/dt exp(-k_d w h),
    w = J M^-1 J^T, through v += M^-1 J^T lambda. Here exp(-x) is replaced by its (0, 2) Pade
    approximant R(x) = 1/(1 + x + x^2/2) (:func:`_decay`: second order, in (0, 1] for all x).
    Applied condition by condition (Gauss-Seidel: each sees the velocities the previous ones left;
    the sum of the conditions' forces is the explicit kernels' damping), forward over the conditions
    for h/2 and backward for h/2 (a symmetric composition). Every update removes kinetic energy and
    keeps the linear momentum, for any h: the damping never limits the step. The integrator
    (``_symplectic_loop``) instead makes one pass per step over h, forward and backward on
    alternate steps. Conservative forces are untouched.

    ``im``: (N,) inverse masses with 0 on driven vertices (their velocities are prescribed).
    ``tnorm``: the triangles' area-weighted normals at ``x`` (:func:`triangle_forces` leaves them),
    used by the dihedral bending. ``quad``: the quadratic bending's condition |sum_j K_j x_j|
    (``bquad``) instead of the dihedral angle. Units as in :func:`triangle_forces` / :func:`bend_forces_fused`.
    """
    to = color_order(tris, x.shape[0])
    eo = color_order(edges, x.shape[0])
    membrane_damping(x, v, tris, coef, area, kd_stretch, kd_shear, im, 0.5 * h, False, to)
    bend_damping(x, v, edges, etris, tnorm, bcoef, bquad, quad, kd_bend, im, 0.5 * h, False, eo)
    bend_damping(x, v, edges, etris, tnorm, bcoef, bquad, quad, kd_bend, im, 0.5 * h, True, eo)
    membrane_damping(x, v, tris, coef, area, kd_stretch, kd_shear, im, 0.5 * h, True, to)


@njit(cache=True)
def color_order(elems: np.ndarray, n_vertices: int) -> np.ndarray:
    """An order of ``elems`` (M, k) vertex tuples (triangles, bend stencils) grouped by a greedy
    colouring in which no two elements of a colour share a vertex.

    The Gauss-Seidel damping passes visit elements in this order: consecutive elements of one colour
    touch disjoint vertices, so their updates commute (the result does not depend on the order within
    a colour) and the CPU overlaps them instead of waiting for the previous element's velocity
    writes (about 2x faster than the mesh's order, where neighbours follow each other).
    """
    M = elems.shape[0]
    used = np.zeros(n_vertices, dtype=np.int64)
    color = np.zeros(M, dtype=np.int64)
    ncol = 0
    for e in range(M):
        mask = 0
        for a in range(elems.shape[1]):
            mask |= used[elems[e, a]]
        c = 0
        while c < 62 and (mask >> c) & 1:
            c += 1
        color[e] = c
        for a in range(elems.shape[1]):
            used[elems[e, a]] |= 1 << c
        ncol = max(ncol, c + 1)
    return np.argsort(color, kind="mergesort")


@njit(cache=True, fastmath=True)
def membrane_damping(x: np.ndarray, v: np.ndarray, tris: np.ndarray, coef: np.ndarray, area: np.ndarray,
                     kd_stretch: float, kd_shear: float, im: np.ndarray, h: float, reverse: bool,
                     order: np.ndarray) -> None:
    """One Gauss-Seidel pass of the stretch (u, v) and shear dampings over ``h`` [s] (see
    :func:`damping_sweep`): triangle by triangle in ``order`` (:func:`color_order`), each triangle's
    conditions in the order C_u, C_v, shear; or all of it in reverse order."""
    if kd_stretch == 0.0 and kd_shear == 0.0:
        return
    M = tris.shape[0]
    for tt in range(M):
        t = order[M - 1 - tt] if reverse else order[tt]
        i = tris[t, 0]
        j = tris[t, 1]
        k = tris[t, 2]
        ai = coef[t, 0]; aj = coef[t, 1]; ak = coef[t, 2]
        bi = coef[t, 3]; bj = coef[t, 4]; bk = coef[t, 5]
        mi = im[i]; mj = im[j]; mk = im[k]
        A = area[t]
        wu0 = ai * x[i, 0] + aj * x[j, 0] + ak * x[k, 0]
        wu1 = ai * x[i, 1] + aj * x[j, 1] + ak * x[k, 1]
        wu2 = ai * x[i, 2] + aj * x[j, 2] + ak * x[k, 2]
        wv0 = bi * x[i, 0] + bj * x[j, 0] + bk * x[k, 0]
        wv1 = bi * x[i, 1] + bj * x[j, 1] + bk * x[k, 1]
        wv2 = bi * x[i, 2] + bj * x[j, 2] + bk * x[k, 2]
        lu2 = wu0 * wu0 + wu1 * wu1 + wu2 * wu2
        lv2 = wv0 * wv0 + wv1 * wv1 + wv2 * wv2
        if lu2 < 1e-24 or lv2 < 1e-24:
            continue
        # the triangle's velocities in registers (its three vertices are distinct)
        vi0 = v[i, 0]; vi1 = v[i, 1]; vi2 = v[i, 2]
        vj0 = v[j, 0]; vj1 = v[j, 1]; vj2 = v[j, 2]
        vk0 = v[k, 0]; vk1 = v[k, 1]; vk2 = v[k, 2]
        cs = A * kd_stretch * h
        csh = A * kd_shear * h
        # stretch: J_p = s_p g/|g| with g = w_u (s = a) or w_v (s = b): dC/dt = g . (sum_p s_p v_p) / |g|;
        # the decay factors q do not depend on v, only the shear's on x
        su = (ai * ai * mi + aj * aj * mj + ak * ak * mk)
        sv = (bi * bi * mi + bj * bj * mj + bk * bk * mk)
        xu = cs * su
        qu = cs * (1.0 + 0.5 * xu) / (1.0 + xu * (1.0 + 0.5 * xu))
        xv = cs * sv
        qv = cs * (1.0 + 0.5 * xv) / (1.0 + xv * (1.0 + 0.5 * xv))
        iu = 1.0 / lu2
        iv = 1.0 / lv2
        # shear: J_p = a_p w_v + b_p w_u
        ji0 = ai * wv0 + bi * wu0; ji1 = ai * wv1 + bi * wu1; ji2 = ai * wv2 + bi * wu2
        jj0 = aj * wv0 + bj * wu0; jj1 = aj * wv1 + bj * wu1; jj2 = aj * wv2 + bj * wu2
        jk0 = ak * wv0 + bk * wu0; jk1 = ak * wv1 + bk * wu1; jk2 = ak * wv2 + bk * wu2
        ws = ((ji0 * ji0 + ji1 * ji1 + ji2 * ji2) * mi + (jj0 * jj0 + jj1 * jj1 + jj2 * jj2) * mj
              + (jk0 * jk0 + jk1 * jk1 + jk2 * jk2) * mk)
        xs = csh * ws
        qs = csh * (1.0 + 0.5 * xs) / (1.0 + xs * (1.0 + 0.5 * xs))
        for step in range(3):
            cond = (2 - step) if reverse else step
            if cond == 2:
                if csh == 0.0:
                    continue
                lam = -qs * (ji0 * vi0 + ji1 * vi1 + ji2 * vi2 + jj0 * vj0 + jj1 * vj1 + jj2 * vj2
                             + jk0 * vk0 + jk1 * vk1 + jk2 * vk2)
                ci = lam * mi; cj = lam * mj; ck = lam * mk
                vi0 += ci * ji0; vi1 += ci * ji1; vi2 += ci * ji2
                vj0 += cj * jj0; vj1 += cj * jj1; vj2 += cj * jj2
                vk0 += ck * jk0; vk1 += ck * jk1; vk2 += ck * jk2
                continue
            if cs == 0.0:
                continue
            if cond == 0:
                si = ai; sj = aj; sk = ak; g0 = wu0; g1 = wu1; g2 = wu2; q = qu * iu  # g unnormalised: / |w|^2
            else:
                si = bi; sj = bj; sk = bk; g0 = wv0; g1 = wv1; g2 = wv2; q = qv * iv
            s0 = si * vi0 + sj * vj0 + sk * vk0
            s1 = si * vi1 + sj * vj1 + sk * vk1
            s2 = si * vi2 + sj * vj2 + sk * vk2
            lam = -q * (g0 * s0 + g1 * s1 + g2 * s2)
            ci = lam * si * mi; cj = lam * sj * mj; ck = lam * sk * mk
            vi0 += ci * g0; vi1 += ci * g1; vi2 += ci * g2
            vj0 += cj * g0; vj1 += cj * g1; vj2 += cj * g2
            vk0 += ck * g0; vk1 += ck * g1; vk2 += ck * g2
        v[i, 0] = vi0; v[i, 1] = vi1; v[i, 2] = vi2
        v[j, 0] = vj0; v[j, 1] = vj1; v[j, 2] = vj2
        v[k, 0] = vk0; v[k, 1] = vk1; v[k, 2] = vk2


@njit(cache=True, fastmath=True)
def bend_damping(x: np.ndarray, v: np.ndarray, edges: np.ndarray, etris: np.ndarray, tnorm: np.ndarray,
                 bcoef: np.ndarray, bquad: np.ndarray, quad: bool, kd_bend: float, im: np.ndarray, h: float,
                 reverse: bool, order: np.ndarray) -> None:
    """One Gauss-Seidel pass of the bending damping over ``h`` [s] (see :func:`damping_sweep`), edge by
    edge, in reverse order if asked."""
    E = edges.shape[0]
    # ---- bending: one condition per interior edge
    if kd_bend != 0.0:
        for qq in range(E):
            q = order[E - 1 - qq] if reverse else order[qq]
            i0 = edges[q, 0]; i1 = edges[q, 1]; i2 = edges[q, 2]; i3 = edges[q, 3]
            m0 = im[i0]; m1 = im[i1]; m2 = im[i2]; m3 = im[i3]
            if quad:
                # C = |w|, w = sum K_j x_j: J_j = K_j w/|w|
                k0 = bquad[q, 0]; k1 = bquad[q, 1]; k2 = bquad[q, 2]; k3 = bquad[q, 3]
                w0 = k0 * x[i0, 0] + k1 * x[i1, 0] + k2 * x[i2, 0] + k3 * x[i3, 0]
                w1 = k0 * x[i0, 1] + k1 * x[i1, 1] + k2 * x[i2, 1] + k3 * x[i3, 1]
                w2 = k0 * x[i0, 2] + k1 * x[i1, 2] + k2 * x[i2, 2] + k3 * x[i3, 2]
                wl = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
                if wl < 1e-12:
                    continue
                w0 /= wl; w1 /= wl; w2 /= wl
                g00 = k0 * w0; g01 = k0 * w1; g02 = k0 * w2
                g10 = k1 * w0; g11 = k1 * w1; g12 = k1 * w2
                g20 = k2 * w0; g21 = k2 * w1; g22 = k2 * w2
                g30 = k3 * w0; g31 = k3 * w1; g32 = k3 * w2
                rate_c = kd_bend
            else:
                # the dihedral angle's gradient, as in bend_forces_fused (repeated rather than shared:
                # a helper there would change that hot kernel's compiled arithmetic, and with it every
                # chaotic fit measured so far)
                t1 = etris[q, 0]
                t2 = etris[q, 1]
                n10 = tnorm[t1, 0]; n11 = tnorm[t1, 1]; n12 = tnorm[t1, 2]
                n20 = tnorm[t2, 0]; n21 = tnorm[t2, 1]; n22 = tnorm[t2, 2]
                x00 = x[i0, 0]; x01 = x[i0, 1]; x02 = x[i0, 2]
                e0 = x[i1, 0] - x00; e1 = x[i1, 1] - x01; e2 = x[i1, 2] - x02
                el2 = e0 * e0 + e1 * e1 + e2 * e2
                nn1 = n10 * n10 + n11 * n11 + n12 * n12
                nn2 = n20 * n20 + n21 * n21 + n22 * n22
                if el2 < 1e-24 or nn1 < 1e-30 or nn2 < 1e-30:
                    continue
                el = math.sqrt(el2)
                ie = 1.0 / el
                inv1 = 1.0 / nn1
                inv2 = 1.0 / nn2
                p10 = n10 * inv1; p11 = n11 * inv1; p12 = n12 * inv1
                p20 = n20 * inv2; p21 = n21 * inv2; p22 = n22 * inv2
                d20 = ((x[i2, 0] - x00) * e0 + (x[i2, 1] - x01) * e1 + (x[i2, 2] - x02) * e2) * ie
                d21 = el - d20
                d30 = ((x[i3, 0] - x00) * e0 + (x[i3, 1] - x01) * e1 + (x[i3, 2] - x02) * e2) * ie
                d31 = el - d30
                g20 = -el * p10; g21 = -el * p11; g22 = -el * p12
                g30 = -el * p20; g31 = -el * p21; g32 = -el * p22
                g00 = d21 * p10 + d31 * p20; g01 = d21 * p11 + d31 * p21; g02 = d21 * p12 + d31 * p22
                g10 = d20 * p10 + d30 * p20; g11 = d20 * p11 + d30 * p21; g12 = d20 * p12 + d30 * p22
                rate_c = kd_bend * bcoef[q]
            cd = (g00 * v[i0, 0] + g01 * v[i0, 1] + g02 * v[i0, 2] + g10 * v[i1, 0] + g11 * v[i1, 1]
                  + g12 * v[i1, 2] + g20 * v[i2, 0] + g21 * v[i2, 1] + g22 * v[i2, 2] + g30 * v[i3, 0]
                  + g31 * v[i3, 1] + g32 * v[i3, 2])
            wsum = ((g00 * g00 + g01 * g01 + g02 * g02) * m0 + (g10 * g10 + g11 * g11 + g12 * g12) * m1
                    + (g20 * g20 + g21 * g21 + g22 * g22) * m2 + (g30 * g30 + g31 * g31 + g32 * g32) * m3)
            lam = _decay(cd, rate_c * h, wsum)
            if lam != 0.0:
                c0 = lam * m0; c1 = lam * m1; c2 = lam * m2; c3 = lam * m3
                v[i0, 0] += c0 * g00; v[i0, 1] += c0 * g01; v[i0, 2] += c0 * g02
                v[i1, 0] += c1 * g10; v[i1, 1] += c1 * g11; v[i1, 2] += c1 * g12
                v[i2, 0] += c2 * g20; v[i2, 1] += c2 * g21; v[i2, 2] += c2 * g22
                v[i3, 0] += c3 * g30; v[i3, 1] += c3 * g31; v[i3, 2] += c3 * g32
