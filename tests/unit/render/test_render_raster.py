"""Fast rasteriser against analytic geometry (no pyrender needed)."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.render.primitives import box, grid_sheet, icosphere
from vidsim.render.raster import RasterError, rasterize, rasterize_batch, silhouette, silhouette_batch
from vidsim.video.camera import PinholeCamera, intrinsics, look_at


def _cam(eye=(0.0, 0.0, -2.0), target=(0.0, 0.0, 0.0), up=(0.0, -1.0, 0.0), w=160, h=120, f=150.0, dist=None):
    R, t = look_at(np.array(eye), np.array(target), np.array(up))
    return PinholeCamera(intrinsics(f, None, (w - 1) / 2 + 0.3, (h - 1) / 2 - 0.2), R, t, w, h,
                         np.zeros(5) if dist is None else dist)


def test_fronto_parallel_square_covers_exactly_the_pixel_centres_inside():
    cam = PinholeCamera(intrinsics(100.0, None, 79.5, 59.5), np.eye(3), np.zeros(3), 160, 120)
    z = 2.0
    # square whose image corners are at non-integer pixel positions
    u0, u1, v0, v1 = 40.3, 101.7, 20.6, 80.2
    corners = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]])
    V = np.column_stack([(corners[:, 0] - 79.5) / 100 * z, (corners[:, 1] - 59.5) / 100 * z, np.full(4, z)])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    r = rasterize(V, F, cam)
    uu, vv = np.meshgrid(np.arange(160), np.arange(120))
    expect = (uu >= u0) & (uu <= u1) & (vv >= v0) & (vv <= v1)
    np.testing.assert_array_equal(r.mask, expect)
    np.testing.assert_allclose(r.depth[expect], z, rtol=1e-6)
    assert np.all(np.isinf(r.depth[~expect])) and np.all(r.face[~expect] == -1)
    np.testing.assert_array_equal(silhouette(V, F, cam), expect)


def test_depth_is_perspective_correct_on_a_tilted_plane():
    cam = _cam()
    # plane through the origin with normal n, seen obliquely
    n = np.array([0.3, -0.2, -1.0])
    n /= np.linalg.norm(n)
    V, F = grid_sheet(3, 3, (1.5, 1.5))
    a = np.cross([0.0, 0.0, 1.0], n)
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    V = V[:, :1] * a + V[:, 1:2] * b
    r = rasterize(V, F, cam)
    assert r.mask.sum() > 3000
    # analytic: ray from the camera centre through each pixel hits the plane n.X = 0
    d = cam.ray_directions()
    C = cam.center
    s = -(C @ n) / (d @ n)
    Xhit = C + s[..., None] * d
    z_true = (Xhit @ cam.R.T + cam.t)[..., 2]
    err = np.abs(r.depth[r.mask] - z_true[r.mask])
    assert err.max() < 2e-5  # metres (float32 storage)


def test_barycentrics_reconstruct_the_surface_point_seen_at_the_pixel(rng):
    cam = _cam(eye=(0.4, -0.3, -1.5))
    V, F = icosphere(0.5, 2)
    V = V * np.array([1.0, 0.7, 1.2])
    r = rasterize(V, F, cam, bary=True)
    ii, jj = np.nonzero(r.mask)
    pick = rng.choice(len(ii), 300, replace=False)
    ii, jj = ii[pick], jj[pick]
    f = r.face[ii, jj]
    b1, b2 = r.bary[ii, jj, 0].astype(float), r.bary[ii, jj, 1].astype(float)
    X = (1 - b1 - b2)[:, None] * V[F[f, 0]] + b1[:, None] * V[F[f, 1]] + b2[:, None] * V[F[f, 2]]
    uv = cam.project(X)
    assert np.max(np.abs(uv[:, 0] - jj)) < 2e-3 and np.max(np.abs(uv[:, 1] - ii)) < 2e-3
    np.testing.assert_allclose(cam.to_camera(X)[:, 2], r.depth[ii, jj], rtol=1e-5)


def test_nearest_surface_wins_and_faces_are_the_front_ones():
    cam = _cam()
    V1, F1 = box((0.4, 0.4, 0.4), (0.0, 0.0, -0.5))   # near the camera (camera at z=-2 looking +z)
    V2, F2 = box((1.0, 1.0, 0.2), (0.0, 0.0, 0.5))    # far
    V = np.vstack([V1, V2])
    F = np.vstack([F1, F2 + len(V1)])
    r = rasterize(V, F, cam)
    c = (cam.height // 2, cam.width // 2)
    assert r.face[c] < len(F1)
    np.testing.assert_allclose(r.depth[c], 2.0 - 0.7, atol=1e-5)  # front face of the near box at z=-0.7


def test_triangles_crossing_the_near_plane_are_clipped_not_dropped():
    cam = PinholeCamera(intrinsics(100.0, None, 79.5, 59.5), np.eye(3), np.zeros(3), 160, 120)
    # a floor plane y = 0.5 extending from behind the camera to far in front
    V = np.array([[-5, 0.5, -1.0], [5, 0.5, -1.0], [5, 0.5, 20.0], [-5, 0.5, 20.0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    r = rasterize(V, F, cam, near=0.05)
    # analytic floor depth at row v: y/z = (v - cy)/f  ->  z = 0.5 f / (v - cy)
    rows = np.arange(62, 120)
    z_true = 0.5 * 100 / (rows - 59.5)
    col = 80
    ok = z_true <= 20.0
    np.testing.assert_allclose(r.depth[rows[ok], col], z_true[ok], rtol=1e-5)
    assert r.mask[rows[ok], col].all()
    assert not r.mask[:59, :].any()  # above the horizon nothing
    # wholly behind the camera: dropped
    assert not silhouette(V - np.array([0, 0, 25.0]), F, cam).any()


def test_batch_equals_single_frames(rng):
    cam = _cam()
    V, F = icosphere(0.3, 1)
    Vs = np.stack([V + rng.normal(0, 0.2, 3) for _ in range(4)])
    sb = silhouette_batch(Vs, F, cam)
    d, f = rasterize_batch(Vs, F, cam)
    for k in range(4):
        r = rasterize(Vs[k], F, cam)
        np.testing.assert_array_equal(sb[k], silhouette(Vs[k], F, cam))
        np.testing.assert_array_equal(sb[k], r.mask)
        np.testing.assert_array_equal(d[k], r.depth)
        np.testing.assert_array_equal(f[k], r.face)


def test_distorted_camera_draws_vertices_where_the_camera_projects_them():
    cam = _cam(dist=np.array([-0.25, 0.08, 0.001, -0.002, 0.0]), w=200, h=150, f=180.0)
    V, F = grid_sheet(30, 30, (1.6, 1.2))
    r = rasterize(V, F, cam)
    interior = np.zeros((30, 30), bool)
    interior[1:-1, 1:-1] = True  # border vertices may round to a pixel centre just outside
    uv = cam.project(V[interior.ravel()])
    inside = (uv[:, 0] > 1) & (uv[:, 0] < cam.width - 2) & (uv[:, 1] > 1) & (uv[:, 1] < cam.height - 2)
    iu = np.rint(uv[inside]).astype(int)
    assert r.mask[iu[:, 1], iu[:, 0]].all()
    # the outline is curved (barrel): the top edge's midpoint bows away from the straight corner chord
    ideal = rasterize(V, F, PinholeCamera(cam.K, cam.R, cam.t, cam.width, cam.height))
    assert (r.mask != ideal.mask).sum() > 200


@pytest.mark.parametrize(
    "V,F,match",
    [
        (np.zeros((4, 2)), np.array([[0, 1, 2]]), "'V'"),
        (np.zeros((4, 3)), np.array([[0, 1, 5]]), "'F'"),
        (np.zeros((4, 3)), np.array([[0.0, 1.0, 2.0]]), "integer"),
        (np.full((4, 3), np.nan), np.array([[0, 1, 2]]), "NaN"),
    ],
)
def test_bad_input_names_the_field(V, F, match):
    with pytest.raises(RasterError, match=match):
        rasterize(V, F, _cam())


def test_bad_near_and_camera_are_rejected():
    V, F = box()
    with pytest.raises(ValueError, match="near"):
        silhouette(V, F, _cam(), near=0.0)
    with pytest.raises(ValueError, match="cam"):
        silhouette(V, F, "camera")


def test_far_off_and_degenerate_triangles_are_harmless():
    cam = _cam()
    V = np.array([[0.0, 0.0, 0.0], [1e200, 0.0, 1.0], [0.0, 1e200, 1.0],   # overflowing projection
                  [0.1, 0.1, 0.0], [0.1, 0.1, 0.0], [0.2, 0.3, 0.0]])     # zero-area triangle
    F = np.array([[0, 1, 2], [3, 4, 5]])
    r = rasterize(V, F, cam, bary=True)
    assert np.all(np.isfinite(r.depth[r.mask])) and np.all(r.depth[r.mask] > 0)
    assert not np.any(r.face == 1)  # the degenerate face never wins a pixel
