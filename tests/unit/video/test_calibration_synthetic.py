"""Calibration recovers a known camera and projector from synthetic footage of the target.

The footage is rendered by ray-plane intersection through the true (distorted) camera with
projector light, blur and sensor noise; the estimators see only the images and the target's
printed geometry, and their results are compared with the truth afterwards.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml

from vidsim.video.calibration import (
    ChessboardTarget,
    ProjectorPattern,
    calibrate_camera_from_target,
    calibrate_projector,
    calibrate_scene,
    camera_from_calibration,
    detect_chessboard,
    film_calibration_target,
    render_target_views,
    undistort_normalized,
)
from vidsim.video.camera import PinholeCamera, distort_normalized, intrinsics, look_at

TARGET = ChessboardTarget()
PATTERN = ProjectorPattern(800, 600, (7, 4), 28)


def _board_to_world() -> np.ndarray:
    """The target standing upright in the scene: board x = world x, board y = world -z."""
    T = np.eye(4)
    T[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
    T[:3, 3] = [-0.3, 0.0, 0.6]
    return T


@pytest.fixture(scope="module")
def scene():
    """True camera and projector (world frame, z up) and their filmed calibration session."""
    rng = np.random.default_rng(7)
    R, t = look_at(np.array([0.0, -1.5, 0.5]), np.array([0.0, 0.0, 0.4]), up=np.array([0.0, 0.0, 1.0]))
    cam = PinholeCamera(intrinsics(820, 820, 322.5, 236.0), R, t, 640, 480, [-0.12, 0.05, 0.0005, -0.0004, 0.0])
    Rp, tp = look_at(np.array([0.45, -1.45, 0.65]), np.array([0.25, 0.0, 0.4]), up=np.array([0.0, 0.0, 1.0]))
    proj = PinholeCamera(intrinsics(1100, 1100, 400, 330), Rp, tp, 800, 600)
    T = _board_to_world()
    target_images, projector_images, names = film_calibration_target(
        cam, rng, target=TARGET, projector=proj, pattern=PATTERN, n_views=10, n_projector_views=10, board_to_world=T
    )
    return cam, proj, T, target_images, projector_images, names


def test_undistort_inverts_distort(rng):
    x, y = rng.uniform(-0.5, 0.5, (2, 1000))
    dist = np.array([-0.25, 0.08, 0.001, -0.0005, -0.01])
    xu, yu = undistort_normalized(*distort_normalized(x, y, dist), dist)
    assert np.abs(xu - x).max() < 1e-9 and np.abs(yu - y).max() < 1e-9


def test_rendered_corners_are_detected_where_the_true_camera_projects_them(scene):
    """Renderer and detector agree with the true lens model to a small fraction of a pixel."""
    cam, _, T, target_images, _, names = scene
    c = detect_chessboard(target_images[0], TARGET.pattern_size)
    X = TARGET.object_points() @ T[:3, :3].T + T[:3, 3]
    err = np.linalg.norm(c - cam.project(X), axis=1)
    assert np.median(err) < 0.1 and err.max() < 0.2


def test_detection_order_is_canonical_under_180_degree_rotation(scene):
    """A board seen upside down gives the same physical corner 0 (the frame is unambiguous)."""
    img = scene[3][1]
    h, w = img.shape
    c = detect_chessboard(img, TARGET.pattern_size)
    c_rot = detect_chessboard(cv2.rotate(img, cv2.ROTATE_180), TARGET.pattern_size)
    back = np.column_stack([w - 1 - c_rot[:, 0], h - 1 - c_rot[:, 1]])
    assert np.abs(back - c).max() < 0.3


def test_camera_recovered_from_target_images(scene):
    cam, _, T, target_images, _, names = scene
    res = calibrate_camera_from_target(target_images, TARGET, image_names=names)
    assert res.n_views == len(names) and not res.rejected
    assert res.rms < 0.15
    K, Kt = res.K, cam.K
    assert abs(K[0, 0] / Kt[0, 0] - 1) < 0.01 and abs(K[1, 1] / Kt[1, 1] - 1) < 0.01
    assert abs(K[0, 2] - Kt[0, 2]) < 0.01 * Kt[0, 0] and abs(K[1, 2] - Kt[1, 2]) < 0.01 * Kt[1, 1]
    # the recovered camera in the world frame of the reference target reprojects the target
    # points (truth positions) where the true camera sees them
    est = camera_from_calibration(res, "reference", board_to_world=T)
    X = TARGET.object_points() @ T[:3, :3].T + T[:3, 3]
    err = np.linalg.norm(est.project(X) - cam.project(X), axis=1)
    assert err.max() < 0.5
    assert np.linalg.norm(est.center - cam.center) < 0.01  # metres, camera 1.6 m away


def test_projector_recovered_from_projected_pattern(scene):
    cam, proj, T, target_images, projector_images, names = scene
    res = calibrate_camera_from_target(target_images, TARGET, image_names=names)
    pc = calibrate_projector(res, target_images, projector_images, PATTERN, image_names=names)
    assert len(pc.used) == 10 and not pc.rejected
    assert pc.rms < 0.3 and np.all(pc.per_view_rms < 0.5)
    assert abs(pc.K[0, 0] / proj.K[0, 0] - 1) < 0.015 and abs(pc.K[1, 1] / proj.K[1, 1] - 1) < 0.015
    assert np.linalg.norm(pc.K[:2, 2] - proj.K[:2, 2]) < 10.0  # projector pixels
    R_pc = proj.R @ cam.R.T  # true camera -> projector
    t_pc = proj.t - R_pc @ cam.t
    angle = np.degrees(np.arccos(np.clip((np.trace(pc.R @ R_pc.T) - 1) / 2, -1, 1)))
    assert angle < 0.5
    assert np.linalg.norm(-pc.R.T @ pc.t - (-R_pc.T @ t_pc)) < 0.02  # projector centre, metres


def test_calibrate_scene_gives_calibration_yaml(scene):
    cam, proj, T, target_images, projector_images, names = scene
    out = calibrate_scene(
        target_images, projector_images, target=TARGET, pattern=PATTERN, image_names=names, board_to_world=T
    )
    out = yaml.safe_load(yaml.safe_dump(out))  # plain YAML types only
    assert out["n_views"] == len(names) and out["reference_view"] == "reference"
    assert out["rms_px"] < 0.15 and out["projector_rms_px"] < 0.3 and out["projector_n_views"] == 10
    c = PinholeCamera.from_dict(out["camera"], "camera")
    p = PinholeCamera.from_dict(out["projector"], "projector")
    # scene points near the target: recovered and true cameras agree
    X = np.random.default_rng(0).uniform([-0.3, -0.1, 0.3], [0.5, 0.1, 0.6], (100, 3))
    assert np.median(np.linalg.norm(c.project(X) - cam.project(X), axis=1)) < 0.5
    assert np.median(np.linalg.norm(p.project(X) - proj.project(X), axis=1)) < 1.0
    assert np.linalg.norm(p.center - proj.center) < 0.02


def test_camera_only_scene_has_no_projector(scene):
    cam, _, T, target_images, _, names = scene
    out = calibrate_scene(target_images[:6], None, target=TARGET, image_names=names[:6])
    assert "projector" not in out and out["n_views"] == 6


def test_rendered_images_show_physical_radiance(rng):
    """White paper under ambient light: grey level = 255 * albedo * ambient (within noise)."""
    cam = PinholeCamera(intrinsics(600, 600, 319.5, 239.5), width=640, height=480)
    pose = (np.eye(3), np.array([-0.6, 0.0, 1.0]))  # camera looks at the blank part of the board
    img = render_target_views(cam, [pose], TARGET, rng, ambient=0.5, noise_sigma=1.0, supersample=1)[0]
    patch = img[200:280, 280:360].astype(float)
    assert abs(patch.mean() - 255 * TARGET.white * 0.5) < 1.0
    assert 0.7 < patch.std() < 1.3


def test_projector_pattern_radiance_is_its_raster():
    """The analytic pattern the renderer uses equals the projector's pixel image."""
    v, u = np.mgrid[0 : PATTERN.height, 0 : PATTERN.width].astype(float)
    r = PATTERN.radiance(u, v, 1e-3)
    np.testing.assert_array_equal(r, PATTERN.image())
    # corners sit where four squares meet: box average over a 2-px footprint is 1/2 there
    q = PATTERN.corners()
    np.testing.assert_allclose(PATTERN.radiance(q[:, 0], q[:, 1], 2.0), 0.5, atol=1e-12)


def test_upside_down_projector_is_recovered():
    """A ceiling-mounted (image upside down) projector: the pattern's corner order stays right."""
    rng = np.random.default_rng(11)
    R, t = look_at(np.array([0.0, -1.5, 0.5]), np.array([0.0, 0.0, 0.4]), up=np.array([0.0, 0.0, 1.0]))
    cam = PinholeCamera(intrinsics(820, 820, 322.5, 236.0), R, t, 640, 480)
    Rp, tp = look_at(np.array([0.45, -1.45, 0.65]), np.array([0.25, 0.0, 0.4]), up=np.array([0.0, 0.0, -1.0]))
    proj = PinholeCamera(intrinsics(1100, 1100, 400, 330), Rp, tp, 800, 600)
    ti, pi, names = film_calibration_target(
        cam, rng, target=TARGET, projector=proj, pattern=PATTERN, n_views=5, n_projector_views=6
    )
    out = calibrate_scene(ti, pi, target=TARGET, pattern=PATTERN, image_names=names)
    assert out["projector_n_views"] == 6 and out["projector_rms_px"] < 0.3
    c = PinholeCamera.from_dict(out["camera"])
    p = PinholeCamera.from_dict(out["projector"])
    R_rel, R_rel_true = p.R @ c.R.T, proj.R @ cam.R.T  # camera -> projector, frame independent
    angle = np.degrees(np.arccos(np.clip((np.trace(R_rel @ R_rel_true.T) - 1) / 2, -1, 1)))
    assert angle < 0.5


def test_canonical_order_undoes_reversed_and_mirrored_corner_lists(scene):
    """Whatever order a detector returns (reversed, rows mirrored), the canonical one comes back."""
    from vidsim.video.calibration import _canonical_order

    img = scene[3][2]
    nx, ny = TARGET.pattern_size
    c = detect_chessboard(img, TARGET.pattern_size)
    grid = c.reshape(ny, nx, 2)
    for variant in (grid[::-1, ::-1], grid[:, ::-1], grid[::-1, :]):
        np.testing.assert_array_equal(_canonical_order(img, variant.reshape(-1, 2), (nx, ny)), c)


def test_spread_patterns_cover_the_projector_image():
    from vidsim.video.calibration import CalibrationError, spread_patterns

    base = ProjectorPattern(800, 600, (7, 4), 10)
    pats = spread_patterns(base, 10, 1.0)
    origins = [p.origin for p in pats]
    assert origins[0] == origins[9] and len(set(origins)) == 9  # the 3 x 3 grid, then round again
    s, (nx, ny) = base.square_px, base.pattern_size
    us, vs = sorted({o[0] for o in origins}), sorted({o[1] for o in origins})
    assert us[0] == s and us[-1] == 800 - (nx + 2) * s and vs[0] == s and vs[-1] == 600 - (ny + 2) * s
    c0 = base.corners().mean(0)
    np.testing.assert_allclose(pats[0].corners().mean(0), c0, atol=1.0)  # centre first
    half = spread_patterns(base, 9, 0.5)
    spread_half = np.ptp([p.corners().mean(0) for p in half], axis=0)
    spread_full = np.ptp([p.corners().mean(0) for p in pats], axis=0)
    np.testing.assert_allclose(spread_half, 0.5 * spread_full, atol=1.0)
    with pytest.raises(CalibrationError, match="extent"):
        spread_patterns(base, 4, 0.0)
    with pytest.raises(CalibrationError, match="3 projector patterns for 5 views"):
        calibrate_projector(None, [np.zeros((4, 4))] * 5, [None] * 5, pats[:3])  # neither per view nor per lit view


def test_cloth_scene_projector_is_determined_with_spread_patterns():
    """The cloth scene's narrow camera sees only the middle of a wide projector's image: a checker
    always cast at the projector's centre leaves its intrinsics loose (ten sessions, `python
    benchmarks/bench_projector_calibration.py --spread 0`: fx 870-915 against 900, centre up to
    66 mm off, swatch-region reprojection up to 4.7 px);
    checkers spread over half the way to the image's edges, with the intrinsics and the one
    projector pose refined jointly on all views' points, pin it down (fx within 0.4 %, centre
    within 6.2 mm, reprojection <= 0.68 px over the same ten sessions)."""
    from vidsim.cli.calibrate import board_to_world, target_for
    from vidsim.config import camera_from_config, projector_from_config
    from vidsim.config.cloth import ClothCalibrationConfig, ClothCameraConfig, ClothProjectorConfig
    from vidsim.video.calibration import spread_patterns
    from omegaconf import OmegaConf

    cal = ClothCalibrationConfig()
    cam = camera_from_config(OmegaConf.structured(ClothCameraConfig())).scaled(cal.still_scale)
    proj = projector_from_config(OmegaConf.structured(ClothProjectorConfig()))
    target = target_for(cal.square_size, cal.target_blank_width)
    T = board_to_world(np.asarray(cal.target_origin, float))
    pats = spread_patterns(ProjectorPattern(proj.width, proj.height, square_px=cal.projector_square_px),
                           cal.n_projector_views, cal.projector_pattern_spread)
    rng = np.random.default_rng(101)
    ti, pi, names = film_calibration_target(cam, rng, target=target, projector=proj, pattern=pats, n_views=cal.n_views,
                                            n_projector_views=cal.n_projector_views, board_to_world=T)
    out = calibrate_scene(ti, pi, target=target, pattern=pats, reference_view=0, image_names=names, board_to_world=T)
    assert out["projector_n_views"] >= cal.n_projector_views - 1, out["projector_views_rejected"]
    p = PinholeCamera.from_dict(out["projector"])
    X = np.random.default_rng(0).uniform([-0.4, -0.3, 0.7], [0.4, 0.3, 1.3], (200, 3))  # where the swatch hangs
    reproj = np.linalg.norm(p.project(X) - proj.project(X), axis=1)
    assert abs(p.K[0, 0] / proj.K[0, 0] - 1) < 0.004 and abs(p.K[1, 1] / proj.K[1, 1] - 1) < 0.004
    assert np.linalg.norm(p.center - proj.center) < 0.007
    assert reproj.max() < 0.8 and np.median(reproj) < 0.25
