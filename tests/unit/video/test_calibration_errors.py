"""Bad calibration input gives a CalibrationError (a ValueError) naming the image or field."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vidsim.video.calibration import (
    CalibrationError,
    ChessboardTarget,
    ProjectorPattern,
    calibrate_chessboard,
    calibrate_projector,
    calibrate_scene,
    render_target_views,
)
from vidsim.video.camera import PinholeCamera, intrinsics

TARGET = ChessboardTarget()


@pytest.fixture(scope="module")
def views():
    """Four views of the printed board (no distortion, 1 sample per pixel: fast)."""
    rng = np.random.default_rng(3)
    cam = PinholeCamera(intrinsics(700, 700, 319.5, 239.5), width=640, height=480)
    poses = []
    for ax, ay in [(0.3, 0.0), (-0.3, 0.1), (0.1, 0.35), (-0.2, -0.3)]:
        R, _ = cv2.Rodrigues(np.array([ax, ay, 0.05]))
        poses.append((R, np.array([0.0, 0.0, 0.9]) - R @ np.array([0.16, 0.1, 0.0])))
    return render_target_views(cam, poses, TARGET, rng)


def test_calibration_error_is_a_value_error():
    assert issubclass(CalibrationError, ValueError)


def test_no_board_in_any_image_names_the_images():
    blank = [np.full((480, 640), 120, np.uint8) for _ in range(3)]
    with pytest.raises(CalibrationError, match=r"no 9x6 chessboard found in any image: a\.png, b\.png, c\.png"):
        calibrate_chessboard(blank, image_names=["a.png", "b.png", "c.png"])


def test_too_few_views_names_used_and_rejected(views):
    imgs = views[:2] + [np.zeros((480, 640), np.uint8)]
    with pytest.raises(CalibrationError, match=r"only 2 view\(s\).*v0, v1.*need at least 3.*dark\.png \(no 9x6"):
        calibrate_chessboard(imgs, TARGET.pattern_size, TARGET.square_size, image_names=["v0", "v1", "dark.png"])


def test_images_of_different_sizes_name_the_odd_one(views):
    imgs = list(views[:3]) + [np.zeros((240, 320), np.uint8)]
    with pytest.raises(CalibrationError, match=r"differ in size.*small\.png \(320x240\)"):
        calibrate_chessboard(imgs, image_names=["a", "b", "c", "small.png"])


def test_bad_arrays_and_fields_are_named():
    with pytest.raises(CalibrationError, match=r"image 'x'.*shape \(4, 4, 4, 4\)"):
        calibrate_chessboard([np.zeros((4, 4, 4, 4))], image_names=["x"])
    with pytest.raises(CalibrationError, match="no images"):
        calibrate_chessboard([])
    with pytest.raises(CalibrationError, match="square_size"):
        ChessboardTarget(square_size=-0.01)
    with pytest.raises(CalibrationError, match="board_extent"):
        ChessboardTarget(board_extent=(0.0, 0.1, 0.0, 0.1))
    with pytest.raises(CalibrationError, match="does not fit"):
        ProjectorPattern(200, 150, (7, 4), 40)
    # a 16-bit image was clipped to a white frame ("no chessboard found"); now its range is named
    with pytest.raises(CalibrationError, match=r"image 'deep\.png': pixel values up to 4095"):
        calibrate_chessboard([np.full((48, 64), 4095, np.uint16)], image_names=["deep.png"])


def test_lens_models_beyond_five_coefficients_are_refused(views):
    """OpenCV's rational model returns 14 coefficients; keeping 5 of them would be another lens."""
    with pytest.raises(CalibrationError, match="CALIB_RATIONAL_MODEL"):
        calibrate_chessboard(views, TARGET.pattern_size, TARGET.square_size, flags=cv2.CALIB_RATIONAL_MODEL)


def test_projector_without_pattern_and_mismatched_lists(views):
    with pytest.raises(CalibrationError, match="no projector 'pattern'"):
        calibrate_scene(views, [None] * len(views), target=TARGET)
    res = calibrate_chessboard(views, TARGET.pattern_size, TARGET.square_size)
    with pytest.raises(CalibrationError, match="4 target images but 2 pattern images"):
        calibrate_projector(res, views, views[:2], ProjectorPattern())
    # the pattern images show no projected light: every view is rejected with its reason
    with pytest.raises(CalibrationError, match=r"only 0 view\(s\).*projected 7x4 pattern not found"):
        calibrate_projector(res, views, views, ProjectorPattern())


def test_view_lookup_errors(views):
    res = calibrate_chessboard(views, TARGET.pattern_size, TARGET.square_size, image_names=["a", "b", "c", "d"])
    with pytest.raises(CalibrationError, match="view 'zz' is not among the used views"):
        res.pose("zz")
    with pytest.raises(CalibrationError, match="view index 9 out of range"):
        res.pose(9)


def test_symmetric_boards_are_refused_for_a_world_frame():
    with pytest.raises(CalibrationError, match=r"\(8, 6\).*180 degrees"):
        ChessboardTarget(pattern_size=(8, 6))
    with pytest.raises(CalibrationError, match=r"\(6, 4\).*180 degrees"):
        ProjectorPattern(pattern_size=(6, 4))


def test_scaled_camera_matches_the_resized_image_for_odd_sizes():
    """A 321 x 241 camera at 0.5 gives a 160 x 120 image (cv2.resize's scale 160/321 per axis); K was
    scaled by exactly 0.5, so the right-most pixel projected 0.5 px off the resized image's."""
    import numpy as np

    from vidsim.video.camera import PinholeCamera, intrinsics

    cam = PinholeCamera(intrinsics(300.0, None, 160.0, 120.0), width=321, height=241)
    half = cam.scaled(0.5)
    assert (half.width, half.height) == (160, 120)
    X = np.array([[0.3, -0.2, 2.0], [-0.5, 0.4, 3.0]])
    u, u2 = cam.project(X), half.project(X)
    sx, sy = 160 / 321, 120 / 241
    assert np.allclose(u2[:, 0], sx * (u[:, 0] + 0.5) - 0.5) and np.allclose(u2[:, 1], sy * (u[:, 1] + 0.5) - 0.5)
    even = PinholeCamera(intrinsics(300.0, None, 159.5, 119.5), width=320, height=240).scaled(0.5)
    assert np.isclose(even.K[0, 0], 150.0) and np.isclose(even.K[0, 2], 79.5)
