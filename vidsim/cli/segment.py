"""Stage ``segment``: silhouettes from the footage alone (per-pixel background model of the clip).

``python -m vidsim.cli.segment paths.footage=results/footage/rigid_101 paths.out=results/rigid/101``
writes ``masks.npz`` (``masks`` (N, H, W) bool, ``times`` (N,) s: the format of
:data:`vidsim.rigid.outputs.MASKS_FORMAT_DOC`), ``segment.yaml`` (per-frame areas, frames with an
object, time taken) and ``segment_sheet.png`` (outlines over the frames that show the object).
Settings: ``rigid.segment.*``. Footage in which no frame shows an object is an error.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli._rigid import RigidStageError, plain, segment_config
from vidsim.io.atomic import write_npz, write_yaml
from vidsim.io.footage import read_footage
from vidsim.log.progress import Progress
from vidsim.report.figures import contact_sheet
from vidsim.rigid.outputs import overlay
from vidsim.video.segment import segment


def run(cfg: DictConfig) -> None:
    if not cfg.paths.footage:
        raise RigidStageError("paths.footage is empty: give the footage folder to segment")
    fo = read_footage(cfg.paths.footage)
    out = Path(cfg.paths.out)
    sc = segment_config(cfg.rigid.segment)
    prog = Progress(1, "segment", enabled=cfg.log.progress)
    t = time.perf_counter()
    masks = segment(fo.frames, cfg=sc)
    secs = time.perf_counter() - t
    prog.update(note=f"{len(masks)} frames")
    area = masks.reshape(len(masks), -1).sum(1)
    shown = np.flatnonzero(area > 0)
    if shown.size == 0:
        raise RigidStageError(f"{fo.path}: the segmentation found no object in any of the {len(masks)} frames "
                              "(empty silhouette in every frame): is the object in view and different from "
                              "the background? (settings: rigid.segment)")
    write_yaml(out / "segment.yaml", {
        "footage": str(fo.path), "n_frames": int(len(masks)), "frames_with_object": int(shown.size),
        "first_frame_with_object": int(shown[0]), "last_frame_with_object": int(shown[-1]),
        "area_px": area.tolist(), "seconds": secs, "settings": plain(cfg.rigid.segment)})
    pick = shown[np.linspace(0, shown.size - 1, min(8, shown.size)).round().astype(int)]
    contact_sheet(overlay(fo.frames[pick], masks[pick]), out / "segment_sheet.png",
                  titles=[f"frame {i}: {area[i]} px" for i in pick])
    # the masks (what fit_rigid reads) last, so a new masks.npz is never found beside an old
    # summary or sheet
    write_npz(out / "masks.npz", masks=masks.astype(bool), times=np.asarray(fo.times, float))
    print(f"segment: object in {shown.size}/{len(masks)} frames ({secs:.1f} s) -> {out / 'masks.npz'}")


main = stage_app("segment", run)

if __name__ == "__main__":
    main()
