"""Fast z-buffer triangle rasteriser (numba) for optimisation inner loops.

This is the cheap renderer used when thousands of frames must be drawn per objective
evaluation: rigid-body silhouettes, cloth depth and structured-light stripes.

Conventions (identical to :mod:`vidsim.video.camera` and to :class:`vidsim.render.scene.Renderer`):

* A world point ``X`` (metres) has camera coordinates ``x_c = R X + t``; the camera looks
  along +z, image x right, image y down.
* Pixel ``(row i, column j)`` is sampled at its centre, the continuous pixel coordinate
  ``(u, v) = (j, i)`` (OpenCV: ``(0, 0)`` is the centre of the top-left pixel). A pixel is
  covered when its centre lies inside the projected triangle (edges included, so two
  triangles sharing an edge may both claim a pixel exactly on it; the z-test decides).
* ``depth`` is camera z (not the ray length), in metres, interpolated perspective-correctly;
  background is ``np.inf``.

Approximations, stated:

* Lens distortion (``cam.dist`` non-zero): vertices are projected *with* distortion and the
  triangle edges between them are rasterised as straight lines. A real lens bends those
  edges; the error grows with triangle size and distance from the principal point and is
  below a pixel for triangles spanning a few tens of pixels under mild distortion. Depth
  and barycentrics inside such a triangle are interpolated in the distorted image.
  Distortion polynomials fold over far outside the field of view; keep geometry roughly
  within the calibrated view when distortion is strong.
* Near plane: triangles are *clipped* against the plane ``z = near`` in camera space
  (Sutherland-Hodgman, giving one or two triangles); triangles wholly at ``z <= near`` are
  dropped. There is no far plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from vidsim.video.camera import PinholeCamera

__all__ = [
    "RasterError",
    "RasterResult",
    "rasterize",
    "rasterize_batch",
    "silhouette",
    "silhouette_batch",
    "face_normals",
    "DEFAULT_NEAR",
]

DEFAULT_NEAR = 1e-3
"""Default near-plane distance in metres."""


class RasterError(ValueError):
    """Input to the rasteriser has the wrong shape, type or values."""


@dataclass
class RasterResult:
    """Output of :func:`rasterize`.

    Attributes:
        depth: (H, W) float32 camera-z of the nearest surface in metres; ``np.inf`` on background.
        face: (H, W) int32 index of the visible triangle; -1 on background.
        bary: (H, W, 2) float32 perspective-correct barycentric weights ``(b1, b2)`` of the
            triangle's vertices ``F[f, 1]`` and ``F[f, 2]`` (``b0 = 1 - b1 - b2``), or None when
            not requested. Zero on background.
    """

    depth: np.ndarray
    face: np.ndarray
    bary: np.ndarray | None = None

    @property
    def mask(self) -> np.ndarray:
        """(H, W) bool coverage."""
        return self.face >= 0


# --------------------------------------------------------------------------- kernels
@njit(cache=True, inline="always")
def _proj(x: float, y: float, z: float, K: np.ndarray, dist: np.ndarray, use_dist: bool):
    xn = x / z
    yn = y / z
    if use_dist:
        k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
        r2 = xn * xn + yn * yn
        radial = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
        xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn)
        yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn
        xn, yn = xd, yd
    u = K[0, 0] * xn + K[0, 1] * yn + K[0, 2]
    v = K[1, 1] * yn + K[1, 2]
    return u, v


@njit(cache=True)
def _tri(
    u0, v0, w0, u1, v1, w1, u2, v2, w2,
    A, fid, H, W, mode, zbuf, fbuf, bbuf, mask,
):
    """Rasterise one projected triangle. ``w`` = 1/z. ``A`` (3, 3): rows = original barycentrics
    of the three vertices. mode 0: mask only; 1: depth + face; 2: + barycentrics."""
    area = (u1 - u0) * (v2 - v0) - (u2 - u0) * (v1 - v0)
    if abs(area) < 1e-14 or not np.isfinite(area):
        return
    inv_area = 1.0 / area
    # clamp in floating point first: far-off vertices must not overflow the int conversion
    fxmin = max(0.0, np.ceil(min(u0, min(u1, u2))))
    fxmax = min(W - 1.0, np.floor(max(u0, max(u1, u2))))
    fymin = max(0.0, np.ceil(min(v0, min(v1, v2))))
    fymax = min(H - 1.0, np.floor(max(v0, max(v1, v2))))
    if not (fxmin <= fxmax and fymin <= fymax):
        return
    xmin, xmax, ymin, ymax = int(fxmin), int(fxmax), int(fymin), int(fymax)
    # normalised edge functions l_k(x, y) = a_k x + b_k y + c_k (barycentric of vertex k)
    a0 = (v1 - v2) * inv_area
    b0 = (u2 - u1) * inv_area
    c0 = (u1 * v2 - u2 * v1) * inv_area
    a1 = (v2 - v0) * inv_area
    b1 = (u0 - u2) * inv_area
    c1 = (u2 * v0 - u0 * v2) * inv_area
    a2 = (v0 - v1) * inv_area
    b2 = (u1 - u0) * inv_area
    c2 = (u0 * v1 - u1 * v0) * inv_area
    eps = -1e-9
    for y in range(ymin, ymax + 1):
        r0 = b0 * y + c0 + a0 * xmin
        r1 = b1 * y + c1 + a1 * xmin
        r2 = b2 * y + c2 + a2 * xmin
        for x in range(xmin, xmax + 1):
            l0 = r0 + a0 * (x - xmin)
            l1 = r1 + a1 * (x - xmin)
            l2 = r2 + a2 * (x - xmin)
            if l0 >= eps and l1 >= eps and l2 >= eps:
                if mode == 0:
                    mask[y, x] = True
                    continue
                iz = l0 * w0 + l1 * w1 + l2 * w2
                if iz <= 0.0:
                    continue
                z = 1.0 / iz
                if z < zbuf[y, x]:
                    zbuf[y, x] = z
                    fbuf[y, x] = fid
                    if mode == 2:
                        p0 = l0 * w0 * z
                        p1 = l1 * w1 * z
                        p2 = l2 * w2 * z
                        bbuf[y, x, 0] = p0 * A[0, 1] + p1 * A[1, 1] + p2 * A[2, 1]
                        bbuf[y, x, 1] = p0 * A[0, 2] + p1 * A[1, 2] + p2 * A[2, 2]


@njit(cache=True)
def _raster_frame(Xc, F, K, dist, use_dist, near, H, W, mode, zbuf, fbuf, bbuf, mask):
    """Rasterise all faces of one frame given camera-space vertices ``Xc`` (N, 3)."""
    N = Xc.shape[0]
    uv = np.empty((N, 2))
    for i in range(N):
        z = Xc[i, 2]
        if z > near:
            u, v = _proj(Xc[i, 0], Xc[i, 1], z, K, dist, use_dist)
            uv[i, 0] = u
            uv[i, 1] = v
        else:
            uv[i, 0] = np.nan
            uv[i, 1] = np.nan
    ident = np.eye(3)
    poly = np.empty((4, 3))   # clipped polygon, camera coords
    pbar = np.empty((4, 3))   # its barycentrics w.r.t. the original triangle
    sub = np.empty((3, 3))
    for f in range(F.shape[0]):
        i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
        z0, z1, z2 = Xc[i0, 2], Xc[i1, 2], Xc[i2, 2]
        nin = (z0 > near) + (z1 > near) + (z2 > near)
        if nin == 3:
            _tri(uv[i0, 0], uv[i0, 1], 1.0 / z0, uv[i1, 0], uv[i1, 1], 1.0 / z1,
                 uv[i2, 0], uv[i2, 1], 1.0 / z2, ident, f, H, W, mode, zbuf, fbuf, bbuf, mask)
            continue
        if nin == 0:
            continue
        # Sutherland-Hodgman against z > near
        idx = (i0, i1, i2)
        npoly = 0
        for k in range(3):
            a = idx[k]
            b = idx[(k + 1) % 3]
            za = Xc[a, 2]
            zb = Xc[b, 2]
            if za > near:
                poly[npoly, :] = Xc[a, :]
                pbar[npoly, :] = ident[k, :]
                npoly += 1
            if (za > near) != (zb > near):
                s = (near - za) / (zb - za)
                poly[npoly, :] = Xc[a, :] + s * (Xc[b, :] - Xc[a, :])
                poly[npoly, 2] = near
                pbar[npoly, :] = (1.0 - s) * ident[k, :] + s * ident[(k + 1) % 3, :]
                npoly += 1
        ua, va = _proj(poly[0, 0], poly[0, 1], poly[0, 2], K, dist, use_dist)
        for k in range(1, npoly - 1):
            ub, vb = _proj(poly[k, 0], poly[k, 1], poly[k, 2], K, dist, use_dist)
            uc, vc = _proj(poly[k + 1, 0], poly[k + 1, 1], poly[k + 1, 2], K, dist, use_dist)
            sub[0, :] = pbar[0, :]
            sub[1, :] = pbar[k, :]
            sub[2, :] = pbar[k + 1, :]
            _tri(ua, va, 1.0 / poly[0, 2], ub, vb, 1.0 / poly[k, 2], uc, vc, 1.0 / poly[k + 1, 2],
                 sub, f, H, W, mode, zbuf, fbuf, bbuf, mask)


@njit(cache=True)
def _raster_batch(Vs, F, R, t, K, dist, use_dist, near, H, W, mode, zbuf, fbuf, bbuf, mask):
    """Rasterise T frames: ``Vs`` (T, N, 3) world vertices into per-frame buffers."""
    T, N = Vs.shape[0], Vs.shape[1]
    Xc = np.empty((N, 3))
    for fr in range(T):
        for i in range(N):
            for r in range(3):
                Xc[i, r] = R[r, 0] * Vs[fr, i, 0] + R[r, 1] * Vs[fr, i, 1] + R[r, 2] * Vs[fr, i, 2] + t[r]
        _raster_frame(Xc, F, K, dist, use_dist, near, H, W, mode,
                      zbuf[fr], fbuf[fr], bbuf[fr], mask[fr])


# --------------------------------------------------------------------------- checks
def _check_mesh(V: np.ndarray, F: np.ndarray, batch: bool) -> tuple[np.ndarray, np.ndarray]:
    V = np.asarray(V)
    F = np.asarray(F)
    want = 3 if batch else 2
    if V.ndim != want or V.shape[-1] != 3:
        shape = "(T, N, 3)" if batch else "(N, 3)"
        raise RasterError(f"vertices 'V' must have shape {shape}, got {V.shape}")
    if not np.issubdtype(V.dtype, np.number):
        raise RasterError(f"vertices 'V' must be numeric, got dtype {V.dtype}")
    V = np.ascontiguousarray(V, dtype=np.float64)
    if not np.all(np.isfinite(V)):
        raise RasterError("vertices 'V' contain NaN or inf")
    if F.ndim != 2 or F.shape[1] != 3:
        raise RasterError(f"faces 'F' must have shape (M, 3), got {F.shape}")
    if F.size and not np.issubdtype(F.dtype, np.integer):
        raise RasterError(f"faces 'F' must be integer indices, got dtype {F.dtype}")
    F = np.ascontiguousarray(F, dtype=np.int64)
    n = V.shape[-2]
    if F.size and (F.min() < 0 or F.max() >= n):
        raise RasterError(f"faces 'F' index vertices outside [0, {n}) (min {F.min()}, max {F.max()})")
    return V, F


def _check_cam(cam: PinholeCamera) -> None:
    if not isinstance(cam, PinholeCamera):
        raise RasterError(f"'cam' must be a PinholeCamera, got {type(cam).__name__}")


def _check_near(near: float) -> float:
    near = float(near)
    if not np.isfinite(near) or near <= 0:
        raise RasterError(f"'near' must be a positive distance in metres, got {near}")
    return near


def _run(Vs, F, cam, near, mode):
    T = Vs.shape[0]
    H, W = cam.height, cam.width
    if mode == 0:
        zbuf = np.empty((T, 1, 1), np.float32)
        fbuf = np.empty((T, 1, 1), np.int32)
        mask = np.zeros((T, H, W), np.bool_)
    else:
        zbuf = np.full((T, H, W), np.inf, np.float32)
        fbuf = np.full((T, H, W), -1, np.int32)
        mask = np.empty((T, 1, 1), np.bool_)
    bbuf = np.zeros((T, H, W, 2), np.float32) if mode == 2 else np.empty((T, 1, 1, 2), np.float32)
    _raster_batch(Vs, F, cam.R, cam.t, cam.K, cam.dist, bool(np.any(cam.dist)), near,
                  H, W, mode, zbuf, fbuf, bbuf, mask)
    return zbuf, fbuf, bbuf, mask


# --------------------------------------------------------------------------- public API
def rasterize(
    V: np.ndarray, F: np.ndarray, cam: PinholeCamera, *, bary: bool = False, near: float = DEFAULT_NEAR
) -> RasterResult:
    """Z-buffer a triangle mesh into the camera image.

    Args:
        V: (N, 3) vertex positions in world coordinates, metres.
        F: (M, 3) integer vertex indices per triangle (any winding; no culling).
        cam: the camera; its ``width``/``height`` set the image size.
        bary: also return perspective-correct barycentrics (slower).
        near: near-plane distance in metres (triangles are clipped against it).

    Returns:
        :class:`RasterResult` with ``depth`` (H, W) float32 metres (inf background), ``face``
        (H, W) int32 (-1 background) and optionally ``bary`` (H, W, 2) float32.

    Raises:
        RasterError: on malformed vertices, faces, camera or near distance.
    """
    V, F = _check_mesh(V, F, batch=False)
    _check_cam(cam)
    near = _check_near(near)
    z, f, b, _ = _run(V[None], F, cam, near, 2 if bary else 1)
    return RasterResult(depth=z[0], face=f[0], bary=b[0] if bary else None)


def rasterize_batch(
    Vs: np.ndarray, F: np.ndarray, cam: PinholeCamera, *, near: float = DEFAULT_NEAR
) -> tuple[np.ndarray, np.ndarray]:
    """Depth and face maps of T frames of one mesh topology in one compiled call.

    Args:
        Vs: (T, N, 3) world vertex positions per frame, metres.
        F: (M, 3) triangle indices shared by all frames.
        cam: the (static) camera.
        near: near-plane distance in metres.

    Returns:
        ``(depth, face)``: (T, H, W) float32 metres (inf background) and (T, H, W) int32 (-1).
    """
    Vs, F = _check_mesh(Vs, F, batch=True)
    _check_cam(cam)
    z, f, _, _ = _run(Vs, F, cam, _check_near(near), 1)
    return z, f


def silhouette(V: np.ndarray, F: np.ndarray, cam: PinholeCamera, *, near: float = DEFAULT_NEAR) -> np.ndarray:
    """Binary coverage mask of a mesh (cheapest path: no depth test).

    Args:
        V: (N, 3) world vertex positions, metres.
        F: (M, 3) triangle indices.
        cam: the camera.
        near: near-plane distance in metres.

    Returns:
        (H, W) bool, True where a pixel centre is covered by any triangle.
    """
    V, F = _check_mesh(V, F, batch=False)
    _check_cam(cam)
    return _run(V[None], F, cam, _check_near(near), 0)[3][0]


def silhouette_batch(Vs: np.ndarray, F: np.ndarray, cam: PinholeCamera, *, near: float = DEFAULT_NEAR) -> np.ndarray:
    """Silhouettes of T frames in one compiled call.

    Args:
        Vs: (T, N, 3) world vertex positions per frame, metres.
        F: (M, 3) triangle indices shared by all frames.
        cam: the (static) camera.
        near: near-plane distance in metres.

    Returns:
        (T, H, W) bool masks.
    """
    Vs, F = _check_mesh(Vs, F, batch=True)
    _check_cam(cam)
    return _run(Vs, F, cam, _check_near(near), 0)[3]


def face_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Unit face normals ``(v1 - v0) x (v2 - v0)`` normalised, shape (M, 3) (or (T, M, 3) for
    (T, N, 3) vertices). Degenerate faces give a zero vector."""
    V = np.asarray(V, dtype=float)
    F = np.asarray(F)
    a = V[..., F[:, 0], :]
    n = np.cross(V[..., F[:, 1], :] - a, V[..., F[:, 2], :] - a)
    ln = np.linalg.norm(n, axis=-1, keepdims=True)
    return np.divide(n, ln, out=np.zeros_like(n), where=ln > 0)
