"""Stage ``reality_fluid``: simulate a fluid scene and film it into a footage folder, truth beside.

``python -m vidsim.cli.reality_fluid fluid.reality.scene=waterfall paths.out=results/footage/fluid_waterfall``.
The footage folder holds only the frames (and a nominal image-plane camera); the true
velocity field (px/frame from frame t to t+1), the obstacle mask and the dye go to
``<out>.truth.npz`` and the scene settings to ``<out>.truth.yaml``, read only by scoring stages.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.config import to_plain
from vidsim.errors import ConfigError, VidsimError
from vidsim.fluid.footage import SYNTHETIC_SCENES, nominal_camera
from vidsim.fluid.viz import arrow_grid
from vidsim.io.atomic import replace_dir, write_npz
from vidsim.io.footage import recording_path, truth_path, write_footage, write_truth
from vidsim.log import make_logger
from vidsim.log.progress import Progress
from vidsim.report.figures import contact_sheet


def truth_arrays_path(folder: Path) -> Path:
    """The arrays of a fluid footage folder's truth: ``<folder>.truth.npz`` beside it."""
    return truth_path(folder).with_suffix(".npz")


def run(cfg: DictConfig) -> None:
    r = cfg.fluid.reality
    if r.scene not in SYNTHETIC_SCENES:
        raise ConfigError(f"fluid.reality.scene={r.scene!r}, expected one of {SYNTHETIC_SCENES}")
    from vidsim.config.fluid import check_fluid_numbers

    check_fluid_numbers(r, "fluid.reality", {"fps": ("float", 0.0), "jacobi_iters": ("int", 0)})
    from vidsim.reality.fluid import make_scene

    out = Path(cfg.paths.out)
    print(f"reality_fluid: simulating {r.scene} ({r.size}x{r.size}, {r.n_frames} frames)", flush=True)
    foot = make_scene(r.scene, size=r.size, n_frames=r.n_frames, seed=cfg.seed + r.seed, warmup=r.warmup,
                      noise_sigma=r.noise_sigma, jacobi_iters=r.jacobi_iters)
    if not foot.ok:
        raise VidsimError(f"reality_fluid: the {r.scene} solver diverged (non-finite velocity); "
                          "lower fluid.reality.size or raise fluid.reality.jacobi_iters")
    T, H, W, _ = foot.frames.shape
    times = np.arange(T) / r.fps
    tmp = out.with_name(f".{out.name}.part")
    shutil.rmtree(tmp, ignore_errors=True)
    prog = Progress(T, "reality_fluid frames", enabled=cfg.log.progress)
    with make_logger(recording_path(out), "vidsim.reality_fluid", cfg.log.rerun) as lg:
        step = max(4, H // 16)
        for i in range(T):
            lg.set_frame(i)
            lg.image("footage/camera/image", foot.frames[i])
            if i < T - 1:
                o, v = arrow_grid(foot.velocity[i], step, scale=3.0)
                lg.arrows2d("truth/camera/velocity", o, v)
            prog.update()
        meta = {"scene": f"fluid_{r.scene}", "kind": "fluid", "fps_nominal": float(r.fps),
                "units": "pixels; velocities px/frame",
                "camera_note": "nominal image-plane camera (fluid stages work in pixels, no pose)"}
        write_footage(tmp, foot.frames, times, {"camera": nominal_camera(W, H)}, meta)
        contact_sheet(foot.frames, tmp / "contact_sheet.png")
    replace_dir(tmp, out, stale=(truth_path(out), truth_arrays_path(out)))
    write_npz(truth_arrays_path(out), velocity=foot.velocity, solid=foot.solid, dye=foot.dye.astype(np.float16))
    write_truth(out, {**foot.meta, "arrays": truth_arrays_path(out).name,
                      "velocity_units": "px/frame, frame t -> t+1, shape (T-1, H, W, 2)", "config": to_plain(cfg.fluid.reality)})
    print(f"reality_fluid: wrote {T} frames to {out}", flush=True)


main = stage_app("reality_fluid", run)

if __name__ == "__main__":
    main()
