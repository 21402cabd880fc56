"""Stage ``reality_demo``: render the demo clip into a footage folder, truth beside it.

``python -m vidsim.cli.reality_demo paths.calibration=results/calibration/demo/calibration.yaml
paths.out=results/footage/demo``. The footage carries the *estimated* calibration (from the
calibration stage), as a real recording would; the true camera goes only to the truth file.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.config import camera_from_config, to_plain
from vidsim.io.atomic import replace_dir
from vidsim.io.footage import read_calibration, recording_path, truth_path, write_footage, write_truth
from vidsim.log import make_logger
from vidsim.log.progress import Progress
from vidsim.reality.demo import box_mesh, demo_motion
from vidsim.reality.imaging import sensor, textured_wall
from vidsim.video.camera import PinholeCamera
from vidsim.report.figures import contact_sheet


def run(cfg: DictConfig) -> None:
    out = Path(cfg.paths.out)
    if not cfg.paths.calibration:
        from vidsim.errors import ConfigError

        raise ConfigError("paths.calibration is empty: give the calibration.yaml of this scene")
    est_cams = read_calibration(cfg.paths.calibration)
    cam = camera_from_config(cfg.camera)  # the true camera of reality
    rng = np.random.default_rng(cfg.seed + cfg.reality.seed)
    motion, truth = demo_motion(cfg.reality.n_frames, cfg.reality.fps, cfg.reality.lead_in_s, rng)
    V, F = box_mesh()
    from vidsim.render.scene import MeshItem, Renderer

    # the lens: the true camera's distortion plus the effect the calibration does not know
    lens = PinholeCamera(cam.K, cam.R, cam.t, cam.width, cam.height, cam.dist + [cfg.effects.imaging.lens_k1, 0, 0, 0, 0])
    renderer = Renderer(cam.width, cam.height)
    wall = textured_wall(cam.width, cam.height, rng)
    frames = []
    prog = Progress(len(motion.times), "reality_demo frames", enabled=cfg.log.progress)
    # staging folder, moved into place at the end: a killed stage leaves no half-written footage
    tmp = out.with_name(f".{out.name}.part")
    shutil.rmtree(tmp, ignore_errors=True)
    with make_logger(recording_path(out), "vidsim.reality_demo", cfg.log.rerun) as lg:
        for i, t in enumerate(motion.times):
            items = []
            if motion.visible[i]:
                Vw = V @ motion.R[i].T + motion.X[i]
                items.append(MeshItem(Vw, F, color=(0.85, 0.25, 0.15)))
            res = renderer.render(items, lens, background=wall)  # applies the lens distortion
            img = sensor(res.color, rng, cfg.render.noise_sigma, cfg.render.jpeg_quality, cfg.render.blur_sigma_px)
            frames.append(img)
            lg.set_frame(i)
            lg.image("footage/camera/image", img)
            lg.mask("truth/camera/mask", res.mask)
            prog.update()
        frames = np.stack(frames)
        times = motion.times + cfg.effects.imaging.time_offset_s
        meta = {"scene": "demo", "object": {"shape": "box", "size_m": [0.3, 0.1, 0.1]}, "fps_nominal": cfg.reality.fps}
        write_footage(tmp, frames, times, est_cams, meta)
        contact_sheet(frames, tmp / "contact_sheet.png")
    replace_dir(tmp, out, stale=(truth_path(out),))
    write_truth(out, {**truth, "camera": cam.to_dict(), "config": to_plain(cfg)})


main = stage_app("reality_demo", run)

if __name__ == "__main__":
    main()
