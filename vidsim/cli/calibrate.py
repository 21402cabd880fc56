"""Stage ``calibrate``: film a planar target with the scene's camera (and projector), calibrate from the images.

Reality places a large printed chessboard in the scene: at one reference pose (which defines the
world frame, as the seed's Vicon-marked grid did) and at ``calibrate.n_views - 1`` further
poses. Only the rendered images go to the estimator (:func:`calibrate_scene`); the true camera
from the config is read afterwards to score the result in ``summary.csv``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.config import camera_from_config
from vidsim.errors import VidsimError
from vidsim.io.atomic import write_text, write_yaml
from vidsim.log import make_logger
from vidsim.video.calibration import ChessboardTarget, board_poses_facing_camera, calibrate_scene, render_target_views
from vidsim.video.camera import PinholeCamera

# the reference board: vertical, facing -y (towards the camera), its x along world x and its
# y (rows of corners) pointing down; it defines the scene's world frame (z up)
TARGET = ChessboardTarget(pattern_size=(9, 6), square_size=0.1, board_extent=(-0.2, 1.1, -0.2, 0.8))
R_BW = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
T_BW = np.array([-0.4, 0.0, 1.5])


def board_to_world() -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R_BW, T_BW
    return T


def film_target(cam: PinholeCamera, n_views: int, rng: np.random.Generator, noise_sigma: float) -> list[np.ndarray]:
    """Reality: images of the target at the reference pose and at ``n_views - 1`` random poses."""
    R_ref = cam.R @ R_BW
    t_ref = cam.R @ T_BW + cam.t
    centre = np.array([0.4, 0.25, 0.0])
    near = R_ref @ centre + t_ref
    poses = [(R_ref, t_ref)]
    for frac in np.linspace(0.45, 0.9, n_views - 1):
        poses += board_poses_facing_camera(1, rng, centre, near * frac, max_tilt_deg=35.0, jitter=0.05)
    return render_target_views(cam, poses, TARGET, rng, noise_sigma=noise_sigma)


def run(cfg: DictConfig) -> None:
    cam_true = camera_from_config(cfg.camera)
    rng = np.random.default_rng(cfg.seed + 101)
    images = film_target(cam_true, cfg.calibrate.n_views, rng, cfg.calibrate.noise_sigma)
    names = [f"target_{i:02d}" for i in range(len(images))]
    calib = calibrate_scene(images, target=TARGET, reference_view="target_00", image_names=names, board_to_world=board_to_world())
    if calib["rms_px"] > cfg.calibrate.max_rms_px:
        raise VidsimError(f"calibration RMS {calib['rms_px']:.3f} px exceeds calibrate.max_rms_px = {cfg.calibrate.max_rms_px}")
    out = Path(cfg.paths.out)
    est = PinholeCamera.from_dict(calib["camera"])
    # scoring against the reality's true camera (never used above)
    X = np.random.default_rng(0).uniform([-1, -0.5, 0.3], [1, 0.5, 2.3], (200, 3))
    reproj = np.linalg.norm(est.project(X) - cam_true.project(X), axis=1)
    rows = ["quantity,estimated,true,difference"]
    for k, (i, j) in {"fx": (0, 0), "fy": (1, 1), "cx": (0, 2), "cy": (1, 2)}.items():
        rows.append(f"{k},{est.K[i, j]:.3f},{cam_true.K[i, j]:.3f},{est.K[i, j] - cam_true.K[i, j]:+.3f}")
    rows.append(f"centre_m,{np.round(est.center, 4).tolist()},{np.round(cam_true.center, 4).tolist()},{np.linalg.norm(est.center - cam_true.center):.4f}")
    rows.append(f"rms_px,{calib['rms_px']:.4f},,")
    rows.append(f"scene_reprojection_px_median,{np.median(reproj):.4f},,")
    rows.append(f"scene_reprojection_px_max,{reproj.max():.4f},,")
    write_text(out / "summary.csv", "\n".join(rows) + "\n")
    with make_logger(out / "calibrate.rrd", "vidsim.calibrate", cfg.log.rerun) as lg:
        for i, img in enumerate(images):
            lg.set_frame(i)
            lg.image("calibration/camera/image", img)
        lg.camera("world/camera_estimated", est)
    write_yaml(out / "calibration.yaml", calib)
    print(f"calibrate: RMS {calib['rms_px']:.3f} px; scene points reproject within {np.median(reproj):.3f} px (median) of truth")


main = stage_app("calibrate", run)

if __name__ == "__main__":
    main()
