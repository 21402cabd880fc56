"""Smoothed silhouette mismatch of a box-union body and its image-space pose gradient (seed eq. 3-7).

The silhouette of a union of convex boxes is the union of the convex hulls of each box's eight
projected corners, so it is drawn exactly without triangles. Each pixel gets a soft coverage
``a = clip(0.5 - sd / ramp, 0, 1)`` from its signed distance ``sd`` (pixels) to the nearest hull,
which makes the mismatch a continuous, piecewise-smooth function of the pose (``ramp = 1`` is
ordinary one-pixel anti-aliasing; larger ramps smooth coarse levels).

Per frame the seed's mismatch ``sum_ij |A_real - A_sim|`` (eq. 3) is, for a binary (or soft)
observed mask ``A``, ``sum A + sum a (1 - 2A)``. We add a distance-transform term that grows
outside the observed silhouette so that disjoint silhouettes still attract::

    E_k = sum A + sum_ij a_ij W_ij,   W = 1 - 2A + lam * min(d_out, cap) / scale

(``d_out``: pixel distance to the observed silhouette). With ``lam = 0`` this is exactly eq. 3.
Only pixels inside the simulated silhouette's bounding box are visited. The gradient with respect
to the pose tangent ``[dX (world), dtheta (body axes)]`` is taken by central finite differences in
image space (the seed's ``dA/dq``), in a single compiled call for all frames.
"""

from __future__ import annotations

import cv2
import numpy as np
from numba import njit

from vidsim.rigid.dynamics import quat_exp, quat_mul
from vidsim.video.camera import PinholeCamera


@njit(cache=True)
def _project(P: np.ndarray, K: np.ndarray, dist: np.ndarray, use_dist: bool) -> np.ndarray:
    n = P.shape[0]
    out = np.empty((n, 2))
    for i in range(n):
        z = max(P[i, 2], 1e-6)
        x = P[i, 0] / z
        y = P[i, 1] / z
        if use_dist:
            r2 = x * x + y * y
            rad = 1 + dist[0] * r2 + dist[1] * r2 * r2 + dist[4] * r2 * r2 * r2
            xd = x * rad + 2 * dist[2] * x * y + dist[3] * (r2 + 2 * x * x)
            yd = y * rad + dist[2] * (r2 + 2 * y * y) + 2 * dist[3] * x * y
            x, y = xd, yd
        out[i, 0] = K[0, 0] * x + K[0, 1] * y + K[0, 2]
        out[i, 1] = K[1, 1] * y + K[1, 2]
    return out


@njit(cache=True)
def _hull(pts: np.ndarray) -> tuple[np.ndarray, int]:
    """Counter-clockwise (in image axes) convex hull of a few 2-D points (monotone chain)."""
    n = pts.shape[0]
    order = np.argsort(pts[:, 0] + 1e-9 * pts[:, 1])
    P = pts[order]
    H = np.empty((2 * n, 2))
    k = 0
    for i in range(n):
        while k >= 2 and ((H[k - 1, 0] - H[k - 2, 0]) * (P[i, 1] - H[k - 2, 1])
                          - (H[k - 1, 1] - H[k - 2, 1]) * (P[i, 0] - H[k - 2, 0])) <= 0:
            k -= 1
        H[k] = P[i]
        k += 1
    lo = k + 1
    for i in range(n - 2, -1, -1):
        while k >= lo and ((H[k - 1, 0] - H[k - 2, 0]) * (P[i, 1] - H[k - 2, 1])
                           - (H[k - 1, 1] - H[k - 2, 1]) * (P[i, 0] - H[k - 2, 0])) <= 0:
            k -= 1
        H[k] = P[i]
        k += 1
    return H, k - 1


@njit(cache=True)
def _edges(pts: np.ndarray) -> tuple[np.ndarray, int]:
    """Edge lines (nx, ny, c) with outward unit normal: signed distance = nx*u + ny*v - c."""
    H, m = _hull(pts)
    E = np.zeros((m, 3))
    cnt = 0
    for i in range(m):
        a = H[i]
        b = H[(i + 1) % m]
        dx = b[0] - a[0]
        dy = b[1] - a[1]
        L = np.sqrt(dx * dx + dy * dy)
        if L < 1e-12:
            continue
        # hull is counter-clockwise in (u right, v down) with cross > 0; outward normal = (dy, -dx)
        nx = dy / L
        ny = -dx / L
        E[cnt, 0] = nx
        E[cnt, 1] = ny
        E[cnt, 2] = nx * a[0] + ny * a[1]
        cnt += 1
    return E, cnt


@njit(cache=True)
def _pose_points(X: np.ndarray, Q: np.ndarray, corners: np.ndarray, Rc: np.ndarray, tc: np.ndarray
                 ) -> np.ndarray:
    """Camera-frame corners (B*8, 3) of the body at world pose (X, Q)."""
    n = Q / np.sqrt(Q[0] ** 2 + Q[1] ** 2 + Q[2] ** 2 + Q[3] ** 2)
    w, x, y, z = n[0], n[1], n[2], n[3]
    R = np.empty((3, 3))
    R[0, 0] = 1 - 2 * (y * y + z * z)
    R[0, 1] = 2 * (x * y - w * z)
    R[0, 2] = 2 * (x * z + w * y)
    R[1, 0] = 2 * (x * y + w * z)
    R[1, 1] = 1 - 2 * (x * x + z * z)
    R[1, 2] = 2 * (y * z - w * x)
    R[2, 0] = 2 * (x * z - w * y)
    R[2, 1] = 2 * (y * z + w * x)
    R[2, 2] = 1 - 2 * (x * x + y * y)
    M = Rc @ R
    c = Rc @ X + tc
    out = corners @ M.T
    for i in range(out.shape[0]):
        out[i] += c
    return out


@njit(cache=True)
def _frame_cost(Pc: np.ndarray, nb: int, K: np.ndarray, dist: np.ndarray, use_dist: bool,
                Wmap: np.ndarray, ramp: float, mode: int, out_img: np.ndarray) -> float:
    """Soft silhouette cost sum(a * W) (mode 0), or write coverage into ``out_img`` (mode 1)."""
    Hh, Ww = Wmap.shape[0], Wmap.shape[1]
    uv = _project(Pc, K, dist, use_dist)
    edges = np.zeros((nb, 16, 3))
    ne = np.zeros(nb, np.int64)
    bb = np.zeros((nb, 4))
    for b in range(nb):
        pts = uv[8 * b:8 * b + 8]
        E, m = _edges(pts)
        edges[b, :m] = E[:m]
        ne[b] = m
        bb[b, 0] = pts[:, 0].min() - ramp
        bb[b, 1] = pts[:, 1].min() - ramp
        bb[b, 2] = pts[:, 0].max() + ramp
        bb[b, 3] = pts[:, 1].max() + ramp
    cost = 0.0
    for b0 in range(nb):
        # visit each part's own bounding box; a pixel shared with an earlier part's box was done there
        j0 = max(0, int(np.ceil(bb[b0, 0])))
        j1 = min(Ww - 1, int(np.floor(bb[b0, 2])))
        i0 = max(0, int(np.ceil(bb[b0, 1])))
        i1 = min(Hh - 1, int(np.floor(bb[b0, 3])))
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                seen = False
                for b in range(b0):
                    if j >= bb[b, 0] and j <= bb[b, 2] and i >= bb[b, 1] and i <= bb[b, 3]:
                        seen = True
                        break
                if seen:
                    continue
                a = 0.0
                for b in range(b0, nb):
                    if j < bb[b, 0] or j > bb[b, 2] or i < bb[b, 1] or i > bb[b, 3]:
                        continue
                    sd = -1e18
                    for e in range(ne[b]):
                        d = edges[b, e, 0] * j + edges[b, e, 1] * i - edges[b, e, 2]
                        if d > sd:
                            sd = d
                    c = 0.5 - sd / ramp
                    if c > a:
                        a = c
                if a <= 0.0:
                    continue
                if a > 1.0:
                    a = 1.0
                if mode == 0:
                    cost += a * Wmap[i, j]
                else:
                    out_img[i, j] = max(out_img[i, j], a)
    return cost


@njit(cache=True)
def _sequence_costs(X: np.ndarray, Q: np.ndarray, corners: np.ndarray, nb: int, K: np.ndarray,
                    Rc: np.ndarray, tc: np.ndarray, dist: np.ndarray, use_dist: bool, Wmaps: np.ndarray,
                    base: np.ndarray, ramp: float, eps_x: np.ndarray, eps_r: np.ndarray, grad: bool
                    ) -> tuple[np.ndarray, np.ndarray]:
    T = X.shape[0]
    costs = np.zeros(T)
    grads = np.zeros((T, 6))
    dummy = np.zeros((1, 1))
    for k in range(T):
        Pc = _pose_points(X[k], Q[k], corners, Rc, tc)
        costs[k] = base[k] + _frame_cost(Pc, nb, K, dist, use_dist, Wmaps[k], ramp, 0, dummy)
        if not grad:
            continue
        for d in range(3):
            Xp = X[k].copy()
            Xp[d] += eps_x[k]
            cp = _frame_cost(_pose_points(Xp, Q[k], corners, Rc, tc), nb, K, dist, use_dist, Wmaps[k], ramp, 0,
                             dummy)
            Xp[d] -= 2 * eps_x[k]
            cm = _frame_cost(_pose_points(Xp, Q[k], corners, Rc, tc), nb, K, dist, use_dist, Wmaps[k], ramp, 0,
                             dummy)
            grads[k, d] = (cp - cm) / (2 * eps_x[k])
        for d in range(3):
            r = np.zeros(3)
            r[d] = eps_r[k]
            Qp = quat_mul(Q[k], quat_exp(r))
            cp = _frame_cost(_pose_points(X[k], Qp, corners, Rc, tc), nb, K, dist, use_dist, Wmaps[k], ramp, 0,
                             dummy)
            r[d] = -eps_r[k]
            Qm = quat_mul(Q[k], quat_exp(r))
            cm = _frame_cost(_pose_points(X[k], Qm, corners, Rc, tc), nb, K, dist, use_dist, Wmaps[k], ramp, 0,
                             dummy)
            grads[k, 3 + d] = (cp - cm) / (2 * eps_r[k])
    return costs, grads


@njit(cache=True)
def _render_soft(X: np.ndarray, Q: np.ndarray, corners: np.ndarray, nb: int, K: np.ndarray, Rc: np.ndarray,
                 tc: np.ndarray, dist: np.ndarray, use_dist: bool, H: int, W: int, ramp: float) -> np.ndarray:
    T = X.shape[0]
    out = np.zeros((T, H, W))
    Wdummy = np.zeros((H, W))
    for k in range(T):
        Pc = _pose_points(X[k], Q[k], corners, Rc, tc)
        _frame_cost(Pc, nb, K, dist, use_dist, Wdummy, ramp, 1, out[k])
    return out


def render_coverage(X: np.ndarray, Q: np.ndarray, box_corners: np.ndarray, cam: PinholeCamera,
                    ramp: float = 1.0) -> np.ndarray:
    """Soft silhouettes of a box-union body.

    Args:
        X: (T, 3) centre-of-mass positions (world = camera-rig frame), metres.
        Q: (T, 4) orientation quaternions (body -> world).
        box_corners: (B, 8, 3) box corners in the body frame, metres.
        cam: camera (its distortion is applied to the corners).
        ramp: width of the anti-aliasing ramp, pixels.

    Returns:
        (T, H, W) float coverage in [0, 1]; ``> 0.5`` is the hard silhouette.
    """
    X = np.ascontiguousarray(X, float).reshape(-1, 3)
    Q = np.ascontiguousarray(Q, float).reshape(-1, 4)
    C = np.ascontiguousarray(box_corners, float).reshape(-1, 8, 3)
    return _render_soft(X, Q, C.reshape(-1, 3), C.shape[0], cam.K, cam.R, cam.t, cam.dist,
                        bool(np.any(cam.dist)), cam.height, cam.width, float(ramp))


def weight_maps(masks: np.ndarray, lam: float, scale: float, cap: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel weights ``W = 1 - 2A + lam * min(d_out, cap) / scale`` and the constants ``sum A``.

    Args:
        masks: (T, H, W) observed silhouettes, bool or soft in [0, 1].
        lam: strength of the distance term (0: exactly the seed's mismatch count).
        scale: distance normaliser, pixels.
        cap: distances are capped here, pixels.

    Returns:
        (T, H, W) float64 weights and (T,) sums of the observed masks.
    """
    A = np.asarray(masks, float)
    W = np.empty_like(A)
    for k in range(A.shape[0]):
        W[k] = 1.0 - 2.0 * A[k]
        if lam > 0:
            outside = (A[k] < 0.5).astype(np.uint8)
            if outside.all():
                d = np.zeros_like(A[k])
            else:
                d = cv2.distanceTransform(outside, cv2.DIST_L2, 5)
            W[k] += lam * np.minimum(d, cap) / scale
    return W, A.reshape(A.shape[0], -1).sum(1)


def sequence_costs(X: np.ndarray, Q: np.ndarray, box_corners: np.ndarray, cam: PinholeCamera,
                   Wmaps: np.ndarray, base: np.ndarray, ramp: float = 1.0, fd_pixels: float = 0.5,
                   grad: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame smoothed mismatch and its image-space finite-difference pose gradient.

    Args:
        X: (T, 3) positions, metres; Q: (T, 4) quaternions.
        box_corners: (B, 8, 3) body-frame box corners, metres.
        cam: camera at the resolution of ``Wmaps``.
        Wmaps: (T, H, W) weights from :func:`weight_maps`; base: (T,) their constants.
        ramp: anti-aliasing ramp, pixels.
        fd_pixels: finite-difference step expressed as image motion, pixels.
        grad: also compute the gradient.

    Returns:
        costs (T,) in pixels (of this resolution) and grads (T, 6) with respect to
        ``[dX (3, world metres), dtheta (3, body axes radians)]``.
    """
    X = np.ascontiguousarray(X, float).reshape(-1, 3)
    Q = np.ascontiguousarray(Q, float).reshape(-1, 4)
    C = np.ascontiguousarray(box_corners, float).reshape(-1, 8, 3)
    f = float(cam.K[0, 0])
    depth = np.maximum((X @ cam.R.T + cam.t)[:, 2], 1e-3)
    rad = float(np.linalg.norm(C.reshape(-1, 3), axis=1).max())
    eps_x = fd_pixels * depth / f
    eps_r = fd_pixels * depth / (f * rad)
    return _sequence_costs(X, Q, C.reshape(-1, 3), C.shape[0], cam.K, cam.R, cam.t, cam.dist,
                           bool(np.any(cam.dist)), np.ascontiguousarray(Wmaps, float),
                           np.ascontiguousarray(base, float), float(ramp), eps_x, eps_r, bool(grad))
