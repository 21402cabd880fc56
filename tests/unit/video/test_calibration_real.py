"""Camera calibration on OpenCV's real chessboard photographs against OpenCV's own reference."""

from __future__ import annotations

import re

import cv2
import numpy as np
import pytest

from vidsim.video.calibration import calibrate_chessboard

pytestmark = pytest.mark.realdata


def _read_reference(path) -> dict:
    """Read the few fields of OpenCV's ``left_intrinsics.yml`` (an OpenCV-FileStorage YAML)."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        ref = {
            "K": fs.getNode("camera_matrix").mat(),
            "dist": fs.getNode("distortion_coefficients").mat().ravel(),
            "rms": fs.getNode("avg_reprojection_error").real(),
            "per_view": fs.getNode("per_view_reprojection_errors").mat().ravel(),
            "nframes": int(fs.getNode("nframes").real()),
        }
    finally:
        fs.release()
    return ref


@pytest.fixture
def left_set(shared_data):
    d = shared_data / "opencv_chessboard"
    if not d.is_dir():
        pytest.skip(f"real data folder {d} is absent")
    files = sorted(p for p in d.glob("left*.jpg") if re.fullmatch(r"left\d+\.jpg", p.name))
    images = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in files]
    return d, files, images


def test_reproduces_opencv_reference_calibration(left_set):
    d, files, images = left_set
    ref = _read_reference(d / "left_intrinsics.yml")
    res = calibrate_chessboard(
        images, (9, 6), 0.025, flags=cv2.CALIB_FIX_ASPECT_RATIO, image_names=[p.name for p in files]
    )
    assert res.n_views == ref["nframes"] == 13 and not res.rejected
    # the numbers published in the data README
    assert abs(res.rms - 0.3926) < 0.01
    assert abs(res.K[0, 0] - 535.9) < 1.0 and abs(res.K[1, 1] - 535.9) < 1.0
    assert abs(res.K[0, 2] - 342.3) < 1.0 and abs(res.K[1, 2] - 235.6) < 1.0
    # and OpenCV's own reference file
    assert abs(res.rms - ref["rms"]) < 0.01
    np.testing.assert_allclose(res.K, ref["K"], atol=1.0)
    np.testing.assert_allclose(res.dist, ref["dist"], atol=0.01)
    # per-view errors: same views, same values (left02 is the worst, about 1.18 px)
    np.testing.assert_allclose(res.per_view_rms, ref["per_view"], atol=0.02)
    assert res.used[int(np.argmax(res.per_view_rms))] == "left02.jpg"
    # boards lie 0.25..0.6 m in front of the camera (25 mm squares, sane metric scale)
    assert np.all((res.tvecs[:, 2] > 0.2) & (res.tvecs[:, 2] < 0.7))


def test_image_without_board_is_rejected_by_name(left_set):
    """A blank frame among real views is listed in ``rejected`` with its reason, the rest are used."""
    d, files, images = left_set
    blank = np.full_like(images[0], 128)
    res = calibrate_chessboard(images[:4] + [blank], image_names=[p.name for p in files[:4]] + ["blank.png"])
    assert res.used == [p.name for p in files[:4]]
    assert "blank.png" in res.rejected and "chessboard" in res.rejected["blank.png"]
