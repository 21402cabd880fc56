"""Stage ``fluid_piv_footage``: a real PIV recording from the shared data as a footage folder.

``python -m vidsim.cli.fluid_piv_footage fluid.piv.name=karman paths.footage=../shared/data/pivlab_karman
paths.out=results/footage/piv_karman``. The frames are area-downsampled by
``fluid.piv.downsample`` (the PIVlab Karman frames are 1024x765: 4x gives 256x191) and written
as RGB; there is no truth (a real recording).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.errors import ConfigError, FootageError
from vidsim.fluid.footage import PIV_RECORDINGS, nominal_camera
from vidsim.fluid.pipeline import prepare_gray_frames
from vidsim.io.footage import read_image, write_footage
from vidsim.log import make_logger
from vidsim.report.figures import contact_sheet
from vidsim.io.atomic import replace_dir

# the frames of each recording, in time order (the jet: exposures A and B of pair 1)
PIV_FILES = {"karman": [f"PIVlab_Karman_0{i}.bmp" for i in range(1, 5)],
             "jet": ["Jet_0001A.jpg", "Jet_0001B.jpg"]}


def run(cfg: DictConfig) -> None:
    p = cfg.fluid.piv
    if p.name not in PIV_RECORDINGS:
        raise ConfigError(f"fluid.piv.name={p.name!r}, expected one of {PIV_RECORDINGS}")
    if p.downsample < 1:
        raise ConfigError(f"fluid.piv.downsample={p.downsample}, expected an integer >= 1")
    from vidsim.config.fluid import check_fluid_numbers

    check_fluid_numbers(p, "fluid.piv", {"fps": ("float", 0.0)})
    src = Path(cfg.paths.footage)
    if not src.is_dir():
        raise FootageError(f"paths.footage={str(src)!r}: PIV recording folder is missing")
    imgs = [read_image(src / f)[..., 0] for f in PIV_FILES[p.name]]  # grey recordings: one channel
    frames = prepare_gray_frames(imgs, downsample=int(p.downsample))
    out = Path(cfg.paths.out)
    tmp = out.with_name(f".{out.name}.part")
    shutil.rmtree(tmp, ignore_errors=True)
    T, H, W, _ = frames.shape
    with make_logger(tmp / "footage.rrd", "vidsim.fluid_piv_footage", cfg.log.rerun) as lg:
        for i, f in enumerate(frames):
            lg.set_frame(i)
            lg.image("footage/camera/image", f)
        meta = {"scene": f"piv_{p.name}", "kind": "fluid", "real": True, "source": str(src),
                "files": PIV_FILES[p.name], "downsample": int(p.downsample), "fps_nominal": float(p.fps),
                "units": "pixels of the downsampled frames; velocities px/frame",
                "camera_note": "nominal image-plane camera (fluid stages work in pixels, no pose)"}
        write_footage(tmp, frames, np.arange(T) / p.fps, {"camera": nominal_camera(W, H)}, meta)
        contact_sheet(frames, tmp / "contact_sheet.png")
    replace_dir(tmp, out)
    print(f"fluid_piv_footage: {p.name}: {T} frames {W}x{H} -> {out}", flush=True)


main = stage_app("fluid_piv_footage", run)

if __name__ == "__main__":
    main()
