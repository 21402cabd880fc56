"""Stage ``calibrate``: film a planar target with the scene's camera (and projector), calibrate from the images.

Reality places a large printed chessboard in the scene: at one reference pose (which defines the
world frame, as the seed's Vicon-marked grid did: vertical, facing the camera, z up) and at
``calibrate.n_views`` further poses; with ``projector.enabled`` also ``calibrate.n_projector_views``
poses where the projector casts a checker onto the board's blank part (at positions spread over
the projector's image, ``calibrate.projector_pattern_spread``; the board is held upside down where
that keeps its print in view). Only the rendered images
go to the estimator (:func:`calibrate_scene`); the true devices from the config are read
afterwards, to score the result in ``summary.csv``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.config import camera_from_config, projector_from_config
from vidsim.errors import VidsimError
from vidsim.io.atomic import write_text, write_yaml
from vidsim.log import make_logger
from vidsim.video.calibration import ChessboardTarget, ProjectorPattern, calibrate_scene, film_calibration_target, spread_patterns
from vidsim.video.camera import PinholeCamera

# 80 mm squares, with a blank area right of the print for the projector's pattern
TARGET = ChessboardTarget(pattern_size=(9, 6), square_size=0.08, board_extent=(-0.16, 1.87, -0.27, 0.67))
# the reference board: its x along world x, its y (rows of corners) pointing down, facing -y
R_BW = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
T_BW = np.array([-0.9, 0.3, 1.6])


def target_for(square_size: float, blank_width: float | None = None) -> ChessboardTarget:
    """The printed target scaled to ``square_size`` metres (the blank projector area scales too,
    unless ``blank_width`` gives its width in metres: a narrow camera needs a narrower board)."""
    if not (np.isfinite(square_size) and square_size > 0):
        raise VidsimError(f"calibrate.square_size = {square_size!r} is not valid: expected > 0 metres")
    k = square_size / TARGET.square_size
    ext = [k * e for e in TARGET.board_extent]
    if blank_width is not None:
        if not (np.isfinite(blank_width) and blank_width > 0):
            raise VidsimError(f"calibrate.target_blank_width = {blank_width!r} is not valid: expected > 0 metres")
        ext[1] = (TARGET.pattern_size[0] + 1) * square_size + float(blank_width)
    return ChessboardTarget(pattern_size=TARGET.pattern_size, square_size=float(square_size), board_extent=tuple(ext))


def board_to_world(origin: np.ndarray | None = None) -> np.ndarray:
    """(4, 4) pose of the reference board in the world (``origin`` in metres, default ``T_BW``)."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R_BW, T_BW if origin is None else np.asarray(origin, float)
    return T


def _score(name: str, est: PinholeCamera, true: PinholeCamera, X: np.ndarray) -> list[str]:
    # only the scene points the true device sees: outside its image the distortion polynomial runs
    # away (the cloth camera scored 11,200 px at points it never images; review, 5 Dec 2026)
    uv = true.project(X, distort=False)
    seen = np.all(np.isfinite(uv), axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] <= true.width - 1) & \
        (uv[:, 1] >= 0) & (uv[:, 1] <= true.height - 1)
    X = X[seen] if seen.any() else X
    reproj = np.linalg.norm(est.project(X) - true.project(X), axis=1)
    rows = [f"{name}_{k},{est.K[i, j]:.3f},{true.K[i, j]:.3f},{est.K[i, j] - true.K[i, j]:+.3f}"
            for k, (i, j) in {"fx": (0, 0), "fy": (1, 1), "cx": (0, 2), "cy": (1, 2)}.items()]
    xyz = lambda c: " ".join(f"{v:.4f}" for v in c)  # noqa: E731  (no commas inside a CSV cell)
    rows.append(f"{name}_centre_m,{xyz(est.center)},{xyz(true.center)},{np.linalg.norm(est.center - true.center):.4f}")
    rows.append(f"{name}_scene_reprojection_px_median,{np.median(reproj):.4f},,")
    rows.append(f"{name}_scene_reprojection_px_max,{reproj.max():.4f},,")
    rows.append(f"{name}_scene_points_scored,{len(X)},,")
    return rows


def run(cfg: DictConfig) -> None:
    cam_true = camera_from_config(cfg.camera)
    proj_true = projector_from_config(cfg.projector) if cfg.projector.enabled else None
    pattern = (ProjectorPattern(width=proj_true.width, height=proj_true.height, square_px=int(cfg.calibrate.projector_square_px))
               if proj_true is not None else None)
    spread = float(cfg.calibrate.projector_pattern_spread)
    if not (np.isfinite(spread) and 0.0 <= spread <= 1.0):
        raise VidsimError(f"calibrate.projector_pattern_spread = {spread!r} is not valid: expected 0 (centred) to 1 (to the image's edges)")
    if pattern is not None and spread > 0 and cfg.calibrate.n_projector_views > 0:
        pattern = spread_patterns(pattern, int(cfg.calibrate.n_projector_views), spread)  # one per projector view
    rng = np.random.default_rng(cfg.seed + 101)
    target = target_for(float(cfg.calibrate.square_size), cfg.calibrate.target_blank_width)
    origin = np.asarray(cfg.calibrate.target_origin, float)
    if origin.shape != (3,) or not np.all(np.isfinite(origin)):
        raise VidsimError(f"calibrate.target_origin = {list(cfg.calibrate.target_origin)} is not valid: expected 3 finite metres")
    k = float(cfg.calibrate.still_scale)
    if not (np.isfinite(k) and k > 0):
        raise VidsimError(f"calibrate.still_scale = {k!r} is not valid: expected > 0 (1 = video resolution)")
    cam_still = cam_true if k == 1.0 else cam_true.scaled(k)
    # reality films the session (stills at k x the video resolution) ...
    tgt, pimgs, names = film_calibration_target(
        cam_still, rng, target=target, projector=proj_true, pattern=pattern, n_views=cfg.calibrate.n_views,
        n_projector_views=cfg.calibrate.n_projector_views, board_to_world=board_to_world(origin),
        noise_sigma=cfg.calibrate.noise_sigma,
    )
    # ... and the estimator sees only the images
    calib = calibrate_scene(tgt, pimgs if proj_true is not None else None, target=target, pattern=pattern,
                            reference_view=0, image_names=names, board_to_world=board_to_world(origin))
    for key in ("rms_px", "projector_rms_px"):
        if calib.get(key, 0.0) > cfg.calibrate.max_rms_px:
            raise VidsimError(f"calibration {key} = {calib[key]:.3f} px exceeds calibrate.max_rms_px = {cfg.calibrate.max_rms_px}")
    if k != 1.0:  # back to the video frames' pixels
        calib["camera"] = PinholeCamera.from_dict(calib["camera"]).scaled(1.0 / k).to_dict()
        calib["still_scale"] = k
    out = Path(cfg.paths.out)
    # scene points scored: a box around the scene, the points each true device images (see _score)
    X = np.random.default_rng(0).uniform([-1, -0.5, 0.3], [1, 0.5, 2.3], (2000, 3))
    est = PinholeCamera.from_dict(calib["camera"])
    rows = ["quantity,estimated,true,difference", f"rms_px,{calib['rms_px']:.4f},,"]
    rows += _score("camera", est, cam_true, X)
    if proj_true is not None:
        rows += [f"projector_rms_px,{calib['projector_rms_px']:.4f},,"]
        rows += _score("projector", PinholeCamera.from_dict(calib["projector"]), proj_true, X)
    write_text(out / "summary.csv", "\n".join(rows) + "\n")
    with make_logger(out / "calibrate.rrd", "vidsim.calibrate", cfg.log.rerun) as lg:
        for i, img in enumerate(tgt):
            lg.set_frame(i)
            lg.image("calibration/camera/image", img)
            if pimgs[i] is not None:
                lg.image("calibration/camera/projector_on", pimgs[i])
        lg.camera("world/camera", est)
    write_yaml(out / "calibration.yaml", calib)
    print(f"calibrate: camera RMS {calib['rms_px']:.3f} px" +
          (f", projector RMS {calib['projector_rms_px']:.3f} px" if proj_true is not None else ""))


main = stage_app("calibrate", run)

if __name__ == "__main__":
    main()
