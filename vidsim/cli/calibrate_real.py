"""Stage ``calibrate_real``: calibrate a camera from real chessboard photos (by default OpenCV's set,
compared with OpenCV's reference).

``python -m vidsim.cli.calibrate_real paths.footage=../shared/data/opencv_chessboard
paths.out=results/calibration/chessboard``. By default uses the left images (``left*``), 9x6 inner
corners, 25 mm squares, ``CALIB_FIX_ASPECT_RATIO`` (as OpenCV's reference run). Your own board:
``calibrate.real.glob='img*' calibrate.real.board=[9,7] calibrate.real.square_size=0.02
calibrate.real.fix_aspect=false``. Writes ``calibration.yaml`` (camera only: the photos have no
scene), ``summary.csv`` (ours, and OpenCV's reference for its own set) and ``reprojection.png``
(per-image RMS).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.errors import FootageError
from vidsim.io.atomic import write_text, write_yaml
from vidsim.io.footage import read_image
from vidsim.report.figures import plt, save_figure
from vidsim.video.calibration import calibrate_chessboard

# OpenCV's own reference calibration of this set (shared/data/README.md, left_intrinsics.yml)
REFERENCE = {"rms_px": 0.3926, "fx": 535.9, "fy": 535.9, "cx": 342.3, "cy": 235.6}


def run(cfg: DictConfig) -> None:
    from vidsim.errors import ConfigError

    rc = cfg.calibrate.real
    folder = Path(cfg.paths.footage)
    if not folder.is_dir():
        raise FootageError(f"{folder}: chessboard image folder is missing")
    board = tuple(int(b) for b in rc.board)
    if len(board) != 2 or min(board) < 2:
        raise ConfigError(f"calibrate.real.board = {list(rc.board)}: expected [inner corners per row, per column], each >= 2")
    if not float(rc.square_size) > 0:
        raise ConfigError(f"calibrate.real.square_size = {rc.square_size}: expected the square's side in metres, > 0")
    exts = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff")
    files = sorted(p for p in folder.glob(str(rc.glob)) if p.is_file() and p.suffix.lower() in exts)
    if not files:
        raise FootageError(f"{folder}: no images match calibrate.real.glob = {rc.glob!r} ({', '.join(exts)})")
    default = (str(rc.glob), board, float(rc.square_size), bool(rc.fix_aspect)) == ("left*", (9, 6), 0.025, True)
    compare = default if rc.compare_reference is None else bool(rc.compare_reference)
    images = [cv2.cvtColor(read_image(p), cv2.COLOR_RGB2GRAY) for p in files]
    res = calibrate_chessboard(images, board, float(rc.square_size),
                               flags=cv2.CALIB_FIX_ASPECT_RATIO if rc.fix_aspect else 0, image_names=[p.name for p in files])
    out = Path(cfg.paths.out)
    w, h = res.image_size
    cam = {"width": w, "height": h, "K": res.K, "dist": res.dist, "R": np.eye(3), "t": np.zeros(3)}
    ours = {"rms_px": res.rms, "fx": res.K[0, 0], "fy": res.K[1, 1], "cx": res.K[0, 2], "cy": res.K[1, 2]}
    if compare:
        rows = ["quantity,vidsim,opencv_reference,difference"]
        rows += [f"{k},{ours[k]:.4f},{REFERENCE[k]:.4f},{ours[k] - REFERENCE[k]:+.4f}" for k in REFERENCE]
        rows += [f"views_used,{res.n_views},13,", f"views_rejected,{len(res.rejected)},,"]
    else:  # a user's own board: no reference to compare with
        rows = ["quantity,vidsim"] + [f"{k},{ours[k]:.4f}" for k in ours]
        rows += [f"views_used,{res.n_views}", f"views_rejected,{len(res.rejected)}"]
    write_text(out / "summary.csv", "\n".join(rows) + "\n")
    fig, ax = plt.subplots(figsize=(7, 3))
    ax.bar(range(res.n_views), res.per_view_rms, color="tab:blue")
    ref = " (OpenCV ref. 0.3926)" if compare else ""
    ax.axhline(res.rms, color="k", ls="--", label=f"overall RMS {res.rms:.4f} px{ref}")
    ax.set_xticks(range(res.n_views), res.used, rotation=60, fontsize=7)
    ax.set_ylabel("reprojection RMS [px]")
    ax.legend(fontsize=8)
    save_figure(fig, out / "reprojection.png")
    write_yaml(out / "calibration.yaml", {"camera": cam})  # the main output last
    print(f"calibrate_real: RMS {res.rms:.4f} px, fx {res.K[0, 0]:.2f}, cx {res.K[0, 2]:.2f}, cy {res.K[1, 2]:.2f} ({res.n_views} views)")


main = stage_app("calibrate_real", run)

if __name__ == "__main__":
    main()
