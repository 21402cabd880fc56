"""Structured light: stripe geometry, radiometry and shadows, on both renderers."""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from vidsim.render import primitives as prim  # noqa: E402
from vidsim.render.projector import Projector, ProjectorError, render_stripes, shade_stripes  # noqa: E402
from vidsim.render.raster import face_normals, rasterize  # noqa: E402
from vidsim.video.camera import PinholeCamera, intrinsics, look_at  # noqa: E402

W, H = 320, 240
AMBIENT = 0.05


def _wall():
    """A 3 m x 2 m wall in the plane y = 0 (normal -y towards the viewers), 2 triangles."""
    V, F = prim.grid_sheet(2, 2, (3.0, 2.0))
    return np.column_stack([V[:, 0], np.zeros(len(V)), V[:, 1]]), F


def _camera() -> PinholeCamera:
    R, t = look_at(np.array([0.0, -2.0, 0.3]), np.array([0.0, 0.0, 0.1]), np.array([0.0, 0.0, 1.0]))
    return PinholeCamera(intrinsics(260.0, None, 161.0, 118.0), R, t, W, H)


def _projector(up=(0.3, 0.0, 1.0), **kw) -> Projector:
    R, t = look_at(np.array([0.7, -1.8, 0.6]), np.array([0.0, 0.0, 0.0]), np.array(up))
    pcam = PinholeCamera(intrinsics(400.0, None, 255.5, 191.5), R, t, 512, 384)
    kw.setdefault("period_px", 16.0)
    kw.setdefault("power", 3.0)
    kw.setdefault("ambient", AMBIENT)
    return Projector(pcam, **kw)


def _wall_point(pcam: PinholeCamera, u: float, v: float) -> np.ndarray:
    """Where the projector ray through pixel (u, v) hits the wall y = 0."""
    d = pcam.R.T @ np.linalg.solve(pcam.K, np.array([u, v, 1.0]))
    C = pcam.center
    return C + (-C[1] / d[1]) * d


def _stripe_angle(img: np.ndarray, region: tuple[slice, slice]) -> float:
    """Dominant stripe direction (degrees mod 180) from the structure tensor of the image gradient."""
    import cv2

    g = img.astype(np.float64)
    gx = cv2.Sobel(g, cv2.CV_64F, 1, 0, ksize=3)[region]
    gy = cv2.Sobel(g, cv2.CV_64F, 0, 1, ksize=3)[region]
    phi = 0.5 * np.arctan2(2 * np.sum(gx * gy), np.sum(gx * gx) - np.sum(gy * gy))  # gradient direction
    return np.degrees(phi + np.pi / 2) % 180.0


def _predicted_angle(cam: PinholeCamera, proj: Projector) -> float:
    v0 = proj.cam.height / 2
    a, b = _wall_point(proj.cam, 150.0, v0), _wall_point(proj.cam, 360.0, v0)
    uv = cam.project(np.stack([a, b]))
    d = uv[1] - uv[0]
    return np.degrees(np.arctan2(d[1], d[0])) % 180.0


def _angle_diff(a: float, b: float) -> float:
    d = abs(a - b) % 180.0
    return min(d, 180.0 - d)


@pytest.fixture(scope="module")
def renderer():
    scene = pytest.importorskip("vidsim.render.scene", reason="pyrender / EGL not available")
    r = scene.Renderer(W, H)
    yield r
    r.close()


def _pyrender_stripes(renderer, meshes, cam, proj):
    from vidsim.render.scene import MeshItem

    items = [MeshItem(V, F, color=(1.0, 1.0, 1.0), name=f"m{k}", in_mask=(k > 0)) for k, (V, F) in enumerate(meshes)]
    return renderer.render(items, cam, projector=proj)


def test_stripes_on_a_plane_have_the_geometric_orientation_and_phase(renderer):
    cam, proj = _camera(), _projector(phase=0.7)
    V, F = _wall()
    pred = _predicted_angle(cam, proj)
    assert 10.0 < pred < 170.0 and _angle_diff(pred, 0.0) > 8.0  # the set-up really tilts the stripes
    fast = render_stripes(V, F, cam, proj)
    ref = _pyrender_stripes(renderer, [(V, F)], cam, proj).irradiance
    region = (slice(60, 180), slice(80, 240))
    for img in (fast, ref):
        assert _angle_diff(_stripe_angle(img, region), pred) < 1.0
        # phase: centres of bright and dark bands (projector rows) land on lit / unlit pixels
        for k in range(8, 16):
            v_bright = (k + proj.phase / (2 * np.pi) + proj.duty / 2) * proj.period_px
            v_dark = v_bright + proj.period_px / 2
            for v, lit in ((v_bright, True), (v_dark, False)):
                uv = cam.project(_wall_point(proj.cam, 256.0, v)[None])[0]
                i, j = np.rint(uv[::-1]).astype(int)
                assert (img[i, j] > AMBIENT + 0.1) == lit, (k, v, img[i, j])


def test_irradiance_follows_inverse_square_and_lambert(renderer):
    cam, proj = _camera(), _projector(period_px=1e6, duty=0.999)  # all bright: a flood light
    V, F = _wall()
    r = rasterize(V, F, cam)
    fast = shade_stripes(r.depth, cam, proj, face_normals(V, F), None, face=r.face)
    ref = _pyrender_stripes(renderer, [(V, F)], cam, proj).irradiance
    # analytic: every pixel's ray meets y = 0; E = ambient + P cos / d^2
    d = cam.ray_directions()
    C = cam.center
    X = C + (-C[1] / d[..., 1])[..., None] * d
    L = proj.cam.center - X
    dist = np.linalg.norm(L, axis=-1)
    cosv = -L[..., 1] / dist  # wall normal (0, -1, 0) faces the projector
    uvp = proj.cam.project(X.reshape(-1, 3)).reshape(H, W, 2)
    inside = (uvp[..., 0] > 1) & (uvp[..., 0] < proj.cam.width - 2) & (uvp[..., 1] > 1) & (uvp[..., 1] < proj.cam.height - 2)
    expect = AMBIENT + proj.power * cosv / dist**2
    m = inside & r.mask
    assert m.sum() > 20000
    assert expect[m].max() / expect[m].min() > 1.2  # the falloff is really exercised
    np.testing.assert_allclose(fast[m], expect[m], rtol=1e-4)
    np.testing.assert_allclose(ref[m], expect[m], rtol=0.02)  # 8-bit colour-coded normals in pyrender's path
    outside = (uvp[..., 0] < -1) | (uvp[..., 0] > proj.cam.width) | (uvp[..., 1] < -1) | (uvp[..., 1] > proj.cam.height)
    assert outside[r.mask].sum() > 1000
    assert np.all(fast[r.mask & outside] <= AMBIENT + 1e-6)  # outside the projector image: ambient only


def _segment_hits_box(P: np.ndarray, Q: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Slab test: does the open segment P->Q (arrays (..., 3)) cross the box [lo, hi]?"""
    d = Q - P
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - P) / d
        t2 = (hi - P) / d
    tmin = np.nanmax(np.minimum(t1, t2), axis=-1)
    tmax = np.nanmin(np.maximum(t1, t2), axis=-1)
    return (tmax >= np.maximum(tmin, 1e-6)) & (tmin <= 1.0)


def test_a_box_casts_its_shadow_where_geometry_says(renderer):
    cam, proj = _camera(), _projector(period_px=1e6, duty=0.999)
    wall = _wall()
    lo, hi = np.array([-0.35, -0.6, -0.2]), np.array([-0.05, -0.35, 0.3])
    box = prim.box(tuple(hi - lo), tuple((hi + lo) / 2))
    V, F = prim.merge(wall, box)
    n_wall = len(wall[1])
    r = rasterize(V, F, cam)
    fast = shade_stripes(r.depth, cam, proj, face_normals(V, F), rasterize(V, F, proj.cam).depth, face=r.face)
    out = _pyrender_stripes(renderer, [wall, box], cam, proj)
    # geometry: wall points seen by the camera, segment to the projector centre blocked by the box
    d = cam.ray_directions()
    C = cam.center
    X = C + (-C[1] / d[..., 1])[..., None] * d
    blocked = _segment_hits_box(X, np.broadcast_to(proj.cam.center, X.shape), lo, hi)
    uvp = proj.cam.project(X.reshape(-1, 3)).reshape(H, W, 2)
    in_beam = (uvp[..., 0] > 1) & (uvp[..., 0] < proj.cam.width - 2) & (uvp[..., 1] > 1) & (uvp[..., 1] < proj.cam.height - 2)
    for name, irr, wall_px in (("fast", fast, (r.face >= 0) & (r.face < n_wall)),
                               ("pyrender", out.irradiance, np.isfinite(out.depth) & ~out.mask)):
        wall_px = wall_px & in_beam
        dark = irr < AMBIENT + 1e-3  # no projector light at all
        pred, meas = blocked & wall_px, dark & wall_px
        assert pred.sum() > 1500, name
        iou = (pred & meas).sum() / (pred | meas).sum()
        assert iou > 0.95, (name, iou)
        assert (pred == meas)[wall_px].mean() > 0.995, name


def test_projector_rejects_bad_fields():
    pcam = _projector().cam
    with pytest.raises(ProjectorError, match="duty"):
        Projector(pcam, duty=1.5)
    with pytest.raises(ProjectorError, match="period_px"):
        Projector(pcam, period_px=0.5)
    with pytest.raises(ProjectorError, match="cam"):
        Projector("projector")
    with pytest.raises(ProjectorError, match="depth_cam"):
        shade_stripes(np.ones((3, 3)), _camera(), _projector(), np.zeros((3, 3, 3)), None)


@pytest.mark.parametrize("dist", [None, (-0.15, 0.03, 0.001, 0.0, 0.0)])
def test_fused_batch_equals_raster_plus_shade_per_frame(rng, dist):
    from vidsim.render.projector import render_stripes_batch

    cam = _camera()
    if dist is not None:
        cam = PinholeCamera(cam.K, cam.R, cam.t, W, H, np.array(dist))
    proj = _projector()
    wall = _wall()
    Vs, F = [], None
    for _ in range(3):
        box = prim.box((0.3, 0.2, 0.4), tuple(rng.uniform([-0.4, -0.6, -0.2], [0.2, -0.3, 0.2])))
        V, F = prim.merge(wall, box)
        Vs.append(V)
    Vs = np.stack(Vs)
    irr, depth = render_stripes_batch(Vs, F, cam, proj)
    for k in range(3):
        r = rasterize(Vs[k], F, cam)
        ref = shade_stripes(r.depth, cam, proj, face_normals(Vs[k], F), rasterize(Vs[k], F, proj.cam).depth, face=r.face)
        np.testing.assert_array_equal(depth[k], r.depth)
        np.testing.assert_allclose(irr[k], ref, atol=1e-6)


def test_undistort_pixels_handles_skew():
    """OpenCV's undistortPoints ignores the skew K[0, 1]; any skewed, distorted camera was refused as
    'distortion cannot be inverted' before the skew was taken out first."""
    from vidsim.render.projector import undistort_pixels

    K = np.array([[500.0, 3.0, 320.0], [0.0, 480.0, 240.0], [0.0, 0.0, 1.0]])
    cam = PinholeCamera(K, width=640, height=480, dist=np.array([-0.05, 0.01, 0.001, -0.002, 0.0]))
    uv = np.array([[10.0, 20.0], [320.0, 240.0], [600.0, 400.0], [630.0, 15.0]])
    xn = undistort_pixels(uv, cam)
    back = cam.project(np.column_stack([xn, np.ones(len(xn))]))
    np.testing.assert_allclose(back, uv, atol=1e-6)
