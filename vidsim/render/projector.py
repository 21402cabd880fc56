"""Structured light: a projector casting horizontal stripes, and the shading it produces.

The cloth metric of the seed (horizontal stripes projected onto the fabric, angle maps of
the striped image) needs the same stripe image from footage and from simulation. The
shading is computed here once, for both renderers:

* :func:`shade_stripes` takes a camera depth map (from :mod:`vidsim.render.raster` or from
  :class:`vidsim.render.scene.Renderer`), normals, and a depth map rendered from the
  projector (shadow map), and returns the light reaching each camera pixel;
* :func:`render_stripes` / :func:`render_stripes_batch` do the whole fast path (two
  rasterisations + shading) for a mesh.

Physics of one camera pixel with surface point ``X`` (world, metres), unit normal ``n``
oriented towards the camera, projector centre ``C``, ``d = |C - X|``, ``l = (C - X) / d``::

    I = ambient + power * s(v_p) * max(0, n . l) / d**2 * lit(X)

where ``v_p`` is the projector image row of ``X`` (continuous pixel coordinate, OpenCV
convention), ``s`` the stripe profile (1 on the bright part of each period, 0 otherwise)
and ``lit`` is 0 when the projector's depth map shows something nearer than ``X`` (beyond a
bias) or when ``X`` falls outside the projector image. ``I`` is a linear radiometric quantity
(no gamma, no noise, no blur; sensor effects belong to the reality code). Background pixels
(``depth = inf``) get 0. With ``power`` in units of "intensity at 1 m", a surface facing a
projector 1 m away on a bright stripe gets ``ambient + power``.

Numba note: the fused batch kernel inlines the rasteriser of :mod:`vidsim.render.raster`;
numba's on-disk cache does not notice edits in another module, so after changing
``raster.py`` clear ``vidsim/render/__pycache__/*.nbi|*.nbc`` (CI starts cold anyway).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit

from vidsim.render.raster import DEFAULT_NEAR, RasterError, _check_cam, _check_mesh, _raster_frame, face_normals
from vidsim.video.camera import PinholeCamera, distort_normalized

__all__ = [
    "ProjectorError",
    "Projector",
    "shade_stripes",
    "render_stripes",
    "render_stripes_batch",
    "camera_rays",
    "undistort_pixels",
]


class ProjectorError(ValueError):
    """A projector description or a shading input is not valid."""


@dataclass
class Projector:
    """A projector casting horizontal stripes (constant along projector image x).

    Attributes:
        cam: the projector as an inverse camera (intrinsics, pose, resolution, distortion).
        period_px: stripe period along the projector image y axis, projector pixels (> 1).
        phase: shift of the pattern, radians (2 pi = one period); the bright part of period k
            starts at projector row ``v = (k + phase / (2 pi)) * period_px``.
        duty: fraction of each period that is bright, in (0, 1).
        power: irradiance on a surface facing the projector 1 m away on a bright stripe
            (arbitrary linear units; images usually use 0..1).
        ambient: irradiance added everywhere on the surface (same units).
        shadow_bias: depth tolerance of the shadow test, metres (a slope term is added).
    """

    cam: PinholeCamera
    period_px: float = 16.0
    phase: float = 0.0
    duty: float = 0.5
    power: float = 1.0
    ambient: float = 0.1
    shadow_bias: float = 0.003

    def __post_init__(self) -> None:
        if not isinstance(self.cam, PinholeCamera):
            raise ProjectorError(f"projector field 'cam' must be a PinholeCamera, got {type(self.cam).__name__}")
        checks = {
            "period_px": (self.period_px, lambda x: x > 1.0, "> 1 projector pixel"),
            "phase": (self.phase, lambda x: True, "a finite angle in radians"),
            "duty": (self.duty, lambda x: 0.0 < x < 1.0, "in (0, 1)"),
            "power": (self.power, lambda x: x >= 0.0, ">= 0"),
            "ambient": (self.ambient, lambda x: x >= 0.0, ">= 0"),
            "shadow_bias": (self.shadow_bias, lambda x: x >= 0.0, ">= 0 metres"),
        }
        for name, (val, ok, what) in checks.items():
            try:
                v = float(val)
            except (TypeError, ValueError) as e:
                raise ProjectorError(f"projector field '{name}' must be a number, got {val!r}") from e
            if not np.isfinite(v) or not ok(v):
                raise ProjectorError(f"projector field '{name}' must be {what}, got {v}")
            setattr(self, name, v)

    def stripe(self, v: np.ndarray) -> np.ndarray:
        """Stripe profile at projector rows ``v`` (pixels, any shape): 1.0 bright, 0.0 dark."""
        s = np.mod(np.asarray(v, float) / self.period_px - self.phase / (2 * np.pi), 1.0)
        return (s < self.duty).astype(float)

    def pattern(self) -> np.ndarray:
        """(Hp, Wp) float image of the projected pattern sampled at projector pixel centres."""
        v = np.arange(self.cam.height, dtype=float)
        return np.repeat(self.stripe(v)[:, None], self.cam.width, axis=1)


# --------------------------------------------------------------------------- geometry helpers
def undistort_pixels(uv: np.ndarray, cam: PinholeCamera, P: np.ndarray | None = None) -> np.ndarray:
    """Invert ``cam``'s lens distortion for pixels ``uv`` (N, 2).

    Returns (N, 2) normalised ideal coordinates ``(x/z, y/z)``, or ideal pixels of the 3x3
    matrix ``P`` when given. Iterative (OpenCV, 100 iterations); checked by re-distorting, and
    :class:`ProjectorError` is raised when the inverse misses by more than 1e-3 px (distortion
    too strong for the field of view).
    """
    pts = np.ascontiguousarray(np.asarray(uv, np.float64).reshape(-1, 1, 2))
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    # OpenCV's undistortPoints ignores the skew K[0,1]; remove it first (u = fx xd + s yd + cx,
    # v = fy yd + cy, so u - s (v - cy) / fy is the pixel of a camera without skew)
    K0 = cam.K.copy()
    q = pts.copy()
    if K0[0, 1] != 0.0:
        q[:, 0, 0] -= K0[0, 1] * (q[:, 0, 1] - K0[1, 2]) / K0[1, 1]
        K0[0, 1] = 0.0
    xn = cv2.undistortPoints(q, K0, cam.dist, R=None, P=None, criteria=crit).reshape(-1, 2)
    xd, yd = distort_normalized(xn[:, 0], xn[:, 1], cam.dist)
    back = np.stack([cam.K[0, 0] * xd + cam.K[0, 1] * yd + cam.K[0, 2], cam.K[1, 1] * yd + cam.K[1, 2]], 1)
    err = np.abs(back - pts.reshape(-1, 2)).max() if len(back) else 0.0
    if not np.isfinite(err) or err > 1e-3:
        raise ProjectorError(f"camera field 'dist' {cam.dist.tolist()}: distortion cannot be inverted over the "
                             f"image (re-projection error {err:.3g} px)")
    if P is None:
        return xn
    P = np.asarray(P, float)
    return np.stack([P[0, 0] * xn[:, 0] + P[0, 1] * xn[:, 1] + P[0, 2], P[1, 1] * xn[:, 1] + P[1, 2]], 1)


def camera_rays(cam: PinholeCamera) -> np.ndarray:
    """(H, W, 2) normalised camera coordinates ``(x/z, y/z)`` of every pixel centre.

    Undistorts with ``cam.dist`` (OpenCV iterative inverse) when the lens is not ideal, so that
    ``X_cam = (x, y, 1) * depth`` back-projects a depth map made with that lens.
    """
    u, v = np.meshgrid(np.arange(cam.width, dtype=np.float64), np.arange(cam.height, dtype=np.float64))
    if np.any(cam.dist):
        und = undistort_pixels(np.stack([u.ravel(), v.ravel()], axis=1), cam)
        return und.reshape(cam.height, cam.width, 2)
    Kinv = np.linalg.inv(cam.K)
    x = Kinv[0, 0] * u + Kinv[0, 1] * v + Kinv[0, 2]
    y = Kinv[1, 1] * v + Kinv[1, 2]
    return np.stack([x, y], axis=-1)


_RAYS_CACHE: dict[bytes, np.ndarray] = {}


def _cached_rays(cam: PinholeCamera) -> np.ndarray:
    """:func:`camera_rays` memoised on the intrinsics, distortion and size (a few cameras per process)."""
    key = cam.K.tobytes() + cam.dist.tobytes() + np.array([cam.width, cam.height]).tobytes()
    if key not in _RAYS_CACHE:
        if len(_RAYS_CACHE) >= 8:
            _RAYS_CACHE.pop(next(iter(_RAYS_CACHE)))
        rays = camera_rays(cam)
        rays.setflags(write=False)
        _RAYS_CACHE[key] = rays
    return _RAYS_CACHE[key]


@njit(cache=True)
def _shade(depth, rays, use_rays, Kinv, idx, nrm, Rc, tc, Kp, Rp, tp, distp, use_dist, Hp, Wp, depth_proj,
           has_shadow, period, phase_frac, duty, power, ambient, bias, out):
    H, W = depth.shape
    Cc = np.empty(3)
    Cp = np.empty(3)
    for r in range(3):  # centres = -R^T t
        Cc[r] = -(Rc[0, r] * tc[0] + Rc[1, r] * tc[1] + Rc[2, r] * tc[2])
        Cp[r] = -(Rp[0, r] * tp[0] + Rp[1, r] * tp[1] + Rp[2, r] * tp[2])
    fp = Kp[1, 1]
    for i in range(H):
        for j in range(W):
            z = depth[i, j]
            k = idx[i, j]
            if not (z < np.inf) or k < 0:
                out[i, j] = 0.0
                continue
            if use_rays:
                rx = rays[i, j, 0]
                ry = rays[i, j, 1]
            else:  # ideal lens: K^-1 (j, i, 1)
                rx = Kinv[0, 0] * j + Kinv[0, 1] * i + Kinv[0, 2]
                ry = Kinv[1, 1] * i + Kinv[1, 2]
            xc = rx * z - tc[0]
            yc = ry * z - tc[1]
            zc = z - tc[2]
            # world point X = R^T (x_cam - t)
            X0 = Rc[0, 0] * xc + Rc[1, 0] * yc + Rc[2, 0] * zc
            X1 = Rc[0, 1] * xc + Rc[1, 1] * yc + Rc[2, 1] * zc
            X2 = Rc[0, 2] * xc + Rc[1, 2] * yc + Rc[2, 2] * zc
            n0, n1, n2 = nrm[k, 0], nrm[k, 1], nrm[k, 2]
            nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            val = ambient
            if nn > 0:
                n0 /= nn
                n1 /= nn
                n2 /= nn
                # orient towards the camera (two-sided opaque surface)
                if n0 * (Cc[0] - X0) + n1 * (Cc[1] - X1) + n2 * (Cc[2] - X2) < 0:
                    n0, n1, n2 = -n0, -n1, -n2
                l0, l1, l2 = Cp[0] - X0, Cp[1] - X1, Cp[2] - X2
                d2 = l0 * l0 + l1 * l1 + l2 * l2
                d = np.sqrt(d2)
                cosv = (n0 * l0 + n1 * l1 + n2 * l2) / d
                if cosv > 0:
                    px = Rp[0, 0] * X0 + Rp[0, 1] * X1 + Rp[0, 2] * X2 + tp[0]
                    py = Rp[1, 0] * X0 + Rp[1, 1] * X1 + Rp[1, 2] * X2 + tp[1]
                    pz = Rp[2, 0] * X0 + Rp[2, 1] * X1 + Rp[2, 2] * X2 + tp[2]
                    if pz > 0:
                        xn = px / pz
                        yn = py / pz
                        if use_dist:
                            r2 = xn * xn + yn * yn
                            rad = 1.0 + distp[0] * r2 + distp[1] * r2 * r2 + distp[4] * r2 * r2 * r2
                            xd = xn * rad + 2.0 * distp[2] * xn * yn + distp[3] * (r2 + 2.0 * xn * xn)
                            yd = yn * rad + distp[2] * (r2 + 2.0 * yn * yn) + 2.0 * distp[3] * xn * yn
                            xn, yn = xd, yd
                        up = Kp[0, 0] * xn + Kp[0, 1] * yn + Kp[0, 2]
                        vp = Kp[1, 1] * yn + Kp[1, 2]
                        iu = int(np.floor(up + 0.5))
                        iv = int(np.floor(vp + 0.5))
                        if iu >= 0 and iu < Wp and iv >= 0 and iv < Hp:
                            lit = True
                            if has_shadow:
                                tanv = np.sqrt(max(0.0, 1.0 - cosv * cosv)) / cosv
                                b = bias + 1.5 * pz / fp * min(tanv, 10.0)
                                if pz > depth_proj[iv, iu] + b:
                                    lit = False
                            if lit:
                                s = vp / period - phase_frac
                                s = s - np.floor(s)
                                if s < duty:
                                    val += power * cosv / d2
            out[i, j] = val


def _as_cam(c, name: str) -> PinholeCamera:
    if not isinstance(c, PinholeCamera):
        raise ProjectorError(f"'{name}' must be a PinholeCamera, got {type(c).__name__}")
    return c


def shade_stripes(
    depth_cam: np.ndarray,
    cam: PinholeCamera,
    projector: Projector,
    normals: np.ndarray,
    depth_proj: np.ndarray | None,
    face: np.ndarray | None = None,
    rays: np.ndarray | None = None,
) -> np.ndarray:
    """Light from a striped projector (plus ambient) reaching each camera pixel.

    Args:
        depth_cam: (H, W) camera-z depth map in metres, ``inf`` (or 0 / NaN) on background.
        cam: the camera that produced ``depth_cam`` (its lens distortion is undone when
            back-projecting).
        projector: the :class:`Projector`.
        normals: either (H, W, 3) per-pixel world normals (``face`` None), or (M, 3) world face
            normals indexed by ``face``. Orientation does not matter (normals are turned towards
            the camera); zero normals get ambient only.
        depth_proj: (Hp, Wp) camera-z depth map rendered from ``projector.cam`` (shadow map,
            inf background), or None to ignore shadows.
        face: (H, W) int face index map (-1 background) when ``normals`` are face normals.
        rays: optional precomputed :func:`camera_rays` of ``cam``; by default an ideal lens is
            inverted on the fly and a distorting lens's rays are computed once and memoised.

    Returns:
        (H, W) float32 irradiance (linear units of ``projector.power``), 0 on background.

    Raises:
        ProjectorError: when shapes do not match the cameras.
    """
    cam = _as_cam(cam, "cam")
    if not isinstance(projector, Projector):
        raise ProjectorError(f"'projector' must be a Projector, got {type(projector).__name__}")
    H, W = cam.height, cam.width
    depth = np.asarray(depth_cam, dtype=np.float32)
    if depth.shape != (H, W):
        raise ProjectorError(f"'depth_cam' must have the camera's shape {(H, W)}, got {depth.shape}")
    depth = np.where(np.isfinite(depth) & (depth > 0), depth, np.float32(np.inf)).astype(np.float32)
    normals = np.asarray(normals, dtype=np.float64)
    if face is None:
        if normals.shape != (H, W, 3):
            raise ProjectorError(f"per-pixel 'normals' must have shape {(H, W, 3)}, got {normals.shape}")
        nrm = np.ascontiguousarray(normals.reshape(-1, 3))
        idx = np.arange(H * W, dtype=np.int32).reshape(H, W)
    else:
        idx = np.ascontiguousarray(face, dtype=np.int32)
        if idx.shape != (H, W):
            raise ProjectorError(f"'face' must have shape {(H, W)}, got {idx.shape}")
        if normals.ndim != 2 or normals.shape[1] != 3:
            raise ProjectorError(f"face 'normals' must have shape (M, 3), got {normals.shape}")
        if idx.size and idx.max() >= normals.shape[0]:
            raise ProjectorError(f"'face' indexes face {idx.max()} but only {normals.shape[0]} normals given")
        nrm = np.ascontiguousarray(normals)
    pc = projector.cam
    if depth_proj is None:
        dp = np.empty((1, 1), np.float32)
        has_shadow = False
    else:
        dp = np.asarray(depth_proj, dtype=np.float32)
        if dp.shape != (pc.height, pc.width):
            raise ProjectorError(f"'depth_proj' must have the projector's shape {(pc.height, pc.width)}, got {dp.shape}")
        dp = np.where(np.isfinite(dp) & (dp > 0), dp, np.float32(np.inf)).astype(np.float32)
        has_shadow = True
    if rays is not None:
        if rays.shape != (H, W, 2):
            raise ProjectorError(f"'rays' must have shape {(H, W, 2)}, got {rays.shape}")
        rays = np.ascontiguousarray(rays, dtype=np.float64)
    elif np.any(cam.dist):
        rays = _cached_rays(cam)
    use_rays = rays is not None
    if not use_rays:
        rays = np.empty((1, 1, 2))
    out = np.empty((H, W), np.float32)
    _shade(depth, rays, use_rays, np.linalg.inv(cam.K), idx, nrm, cam.R, cam.t,
           pc.K, pc.R, pc.t, pc.dist, bool(np.any(pc.dist)), pc.height, pc.width, dp, has_shadow,
           projector.period_px, projector.phase / (2 * np.pi), projector.duty, projector.power,
           projector.ambient, projector.shadow_bias, out)
    return out


def render_stripes_batch(
    Vs: np.ndarray, F: np.ndarray, cam: PinholeCamera, projector: Projector, *,
    shadows: bool = True, near: float = DEFAULT_NEAR,
) -> tuple[np.ndarray, np.ndarray]:
    """Fast-path striped images of T frames of a mesh.

    One compiled loop per call: camera z-buffer, projector shadow map, face normals and
    shading per frame with reused buffers; the result equals :func:`rasterize` +
    :func:`shade_stripes` frame by frame (tested).

    Args:
        Vs: (T, N, 3) world vertices per frame, metres.
        F: (M, 3) triangle indices.
        cam: the camera.
        projector: the projector.
        shadows: render the projector's depth map and shadow with it.
        near: near-plane distance in metres.

    Returns:
        ``(intensity, depth)``: (T, H, W) float32 irradiance (0 background) and (T, H, W)
        float32 camera depth (inf background).
    """
    try:
        Vs, F = _check_mesh(Vs, F, batch=True)
        _check_cam(cam)
        _check_cam(projector.cam)
    except RasterError as e:
        raise ProjectorError(str(e)) from e
    near = float(near)
    if not np.isfinite(near) or near <= 0:
        raise ProjectorError(f"'near' must be a positive distance in metres, got {near}")
    T = Vs.shape[0]
    H, W = cam.height, cam.width
    pc = projector.cam
    use_rays = bool(np.any(cam.dist))
    rays = _cached_rays(cam) if use_rays else np.empty((1, 1, 2))
    depth = np.empty((T, H, W), np.float32)
    out = np.empty((T, H, W), np.float32)
    _stripes_batch(Vs, F, cam.R, cam.t, cam.K, cam.dist, use_rays, rays, np.linalg.inv(cam.K),
                   pc.K, pc.R, pc.t, pc.dist, pc.height, pc.width, bool(shadows), near,
                   projector.period_px, projector.phase / (2 * np.pi), projector.duty, projector.power,
                   projector.ambient, projector.shadow_bias, depth, out)
    return out, depth


@njit(cache=True)
def _stripes_batch(Vs, F, Rc, tc, Kc, distc, use_rays, rays, Kinv, Kp, Rp, tp, distp, Hp, Wp, shadows, near,
                   period, phase_frac, duty, power, ambient, bias, depth, out):
    """Fused per-frame camera raster + projector shadow map + shading, reusing buffers."""
    T, N = Vs.shape[0], Vs.shape[1]
    H, W = depth.shape[1], depth.shape[2]
    M = F.shape[0]
    Xc = np.empty((N, 3))
    Xp = np.empty((N, 3))
    face = np.empty((H, W), np.int32)
    zp = np.empty((Hp, Wp), np.float32) if shadows else np.empty((1, 1), np.float32)
    fp = np.empty((Hp, Wp), np.int32) if shadows else np.empty((1, 1), np.int32)
    nrm = np.empty((M, 3))
    dummy_b = np.empty((1, 1, 2), np.float32)
    dummy_m = np.empty((1, 1), np.bool_)
    use_dist_c = _any_nonzero(distc)
    use_dist_p = _any_nonzero(distp)
    for fr in range(T):
        for i in range(N):
            for r in range(3):
                Xc[i, r] = Rc[r, 0] * Vs[fr, i, 0] + Rc[r, 1] * Vs[fr, i, 1] + Rc[r, 2] * Vs[fr, i, 2] + tc[r]
        zc = depth[fr]
        zc[:, :] = np.inf
        face[:, :] = -1
        _raster_frame(Xc, F, Kc, distc, use_dist_c, near, H, W, 1, zc, face, dummy_b, dummy_m)
        if shadows:
            for i in range(N):
                for r in range(3):
                    Xp[i, r] = Rp[r, 0] * Vs[fr, i, 0] + Rp[r, 1] * Vs[fr, i, 1] + Rp[r, 2] * Vs[fr, i, 2] + tp[r]
            zp[:, :] = np.inf
            _raster_frame(Xp, F, Kp, distp, use_dist_p, near, Hp, Wp, 1, zp, fp, dummy_b, dummy_m)
        for f in range(M):
            a, b, c = F[f, 0], F[f, 1], F[f, 2]
            e1x = Vs[fr, b, 0] - Vs[fr, a, 0]
            e1y = Vs[fr, b, 1] - Vs[fr, a, 1]
            e1z = Vs[fr, b, 2] - Vs[fr, a, 2]
            e2x = Vs[fr, c, 0] - Vs[fr, a, 0]
            e2y = Vs[fr, c, 1] - Vs[fr, a, 1]
            e2z = Vs[fr, c, 2] - Vs[fr, a, 2]
            nrm[f, 0] = e1y * e2z - e1z * e2y
            nrm[f, 1] = e1z * e2x - e1x * e2z
            nrm[f, 2] = e1x * e2y - e1y * e2x
        _shade(zc, rays, use_rays, Kinv, face, nrm, Rc, tc, Kp, Rp, tp, distp, use_dist_p, Hp, Wp, zp,
               shadows, period, phase_frac, duty, power, ambient, bias, out[fr])


@njit(cache=True)
def _any_nonzero(dist):
    """True when any distortion coefficient is non-zero."""
    for q in range(dist.shape[0]):
        if dist[q] != 0.0:
            return True
    return False


def render_stripes(
    V: np.ndarray, F: np.ndarray, cam: PinholeCamera, projector: Projector, *, shadows: bool = True,
    near: float = DEFAULT_NEAR,
) -> np.ndarray:
    """Fast-path striped image of one mesh: (H, W) float32 irradiance (see :func:`shade_stripes`)."""
    V = np.asarray(V)
    if V.ndim != 2:
        raise ProjectorError(f"vertices 'V' must have shape (N, 3), got {V.shape}")
    return render_stripes_batch(V[None], F, cam, projector, shadows=shadows, near=near)[0][0]
