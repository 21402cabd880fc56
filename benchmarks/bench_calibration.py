"""Calibration timings: real chessboard calibration, target rendering, full scene calibration.

Prints the median (and min) wall time of ``--runs`` runs of:

* ``calibrate_chessboard`` on OpenCV's 13 real left images (640x480, 9x6 corners), when the
  shared data folder is present;
* ``render_target_views`` of one 640x480 view of the target with projector light (1 sample
  per pixel; the lens-undistortion ray map is built once per camera and excluded);
* ``calibrate_scene`` on a synthetic session of 21 views (1 reference + 10 camera views +
  10 projector views, each with a projector-on image).

Single-threaded OpenCV. Usage::

    python benchmarks/bench_calibration.py [--runs 5]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time

import cv2
import numpy as np

from vidsim.io.paths import shared_data_dir
from vidsim.video.calibration import (
    ChessboardTarget,
    ProjectorPattern,
    calibrate_chessboard,
    calibrate_scene,
    film_calibration_target,
    render_target_views,
)
from vidsim.video.camera import PinholeCamera, intrinsics, look_at


def timed(fn, runs: int) -> tuple[float, float]:
    """(median, min) wall time of ``runs`` calls, seconds."""
    ts = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), min(ts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    print(f"machine: {platform.machine()} {platform.processor() or ''} python {platform.python_version()} opencv {cv2.__version__}")
    rows = []

    d = shared_data_dir() / "opencv_chessboard"
    if d.is_dir():
        files = sorted(p for p in d.glob("left*.jpg"))
        imgs = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in files]
        med, mn = timed(lambda: calibrate_chessboard(imgs, flags=cv2.CALIB_FIX_ASPECT_RATIO), args.runs)
        rows.append((f"calibrate_chessboard, {len(imgs)} real 640x480 images", med, mn))
    else:
        print(f"(skipping real-data calibration: {d} absent)")

    R, t = look_at(np.array([0.0, -1.5, 0.5]), np.array([0.0, 0.0, 0.4]), up=np.array([0.0, 0.0, 1.0]))
    cam = PinholeCamera(intrinsics(820, 820, 322.5, 236.0), R, t, 640, 480, [-0.12, 0.05, 0.0005, -0.0004, 0.0])
    Rp, tp = look_at(np.array([0.45, -1.45, 0.65]), np.array([0.25, 0.0, 0.4]), up=np.array([0.0, 0.0, 1.0]))
    proj = PinholeCamera(intrinsics(1100, 1100, 400, 330), Rp, tp, 800, 600)
    pattern = ProjectorPattern(800, 600, (7, 4), 28)
    target = ChessboardTarget()
    T = np.eye(4)
    T[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
    T[:3, 3] = [-0.3, 0.0, 0.6]
    rng = np.random.default_rng(0)
    R_pc = proj.R @ cam.R.T
    proj_cam = PinholeCamera(proj.K, R_pc, proj.t - R_pc @ cam.t, 800, 600)
    pose = (cam.R @ T[:3, :3], cam.R @ T[:3, 3] + cam.t)
    render_target_views(cam, [pose], target, rng)  # builds the cached ray map
    med, mn = timed(lambda: render_target_views(cam, [pose], target, rng, projector=proj_cam, pattern=pattern), args.runs)
    rows.append(("render_target_views, one 640x480 view with projector", med, mn))

    ti, pi, names = film_calibration_target(
        cam, rng, target=target, projector=proj, pattern=pattern, n_views=10, n_projector_views=10, board_to_world=T
    )
    med, mn = timed(
        lambda: calibrate_scene(ti, pi, target=target, pattern=pattern, image_names=names, board_to_world=T), args.runs
    )
    rows.append((f"calibrate_scene, {len(ti)} views + 10 projector images", med, mn))

    print(f"{'case':60s} {'median s':>9s} {'min s':>9s}")
    for name, med, mn in rows:
        print(f"{name:60s} {med:9.3f} {mn:9.3f}")


if __name__ == "__main__":
    main()
