"""Stage ``check_footage``: validate a footage folder (yours or a synthetic one) and summarise it.

``python -m vidsim.cli.check_footage paths.footage=my_recording paths.out=results/checks/my_recording
'check.required_meta=[inertia]'`` reads the folder exactly as every estimator does; any problem
ends with one line naming the file and field. On success it writes ``summary.yaml`` (frames,
size, frame-time statistics, devices) and ``contact_sheet.png``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.errors import ConfigError
from vidsim.io.atomic import write_yaml
from vidsim.io.footage import read_footage
from vidsim.report.figures import contact_sheet


def run(cfg: DictConfig) -> None:
    if not cfg.paths.footage:
        raise ConfigError("paths.footage is empty: give the footage folder to check")
    fo = read_footage(cfg.paths.footage, required_meta=tuple(cfg.check.required_meta))
    dt = np.diff(fo.times)
    summary = {
        "footage": str(fo.path),
        "n_frames": int(fo.frames.shape[0]),
        "size_px": [int(fo.frames.shape[2]), int(fo.frames.shape[1])],
        "duration_s": float(fo.times[-1] - fo.times[0]),
        "frame_interval_s": {"median": float(np.median(dt)), "min": float(dt.min()), "max": float(dt.max())} if dt.size else None,
        "devices": {k: {"fx": float(c.K[0, 0]), "fy": float(c.K[1, 1]), "distorted": bool(np.any(c.dist))} for k, c in fo.cameras.items()},
        "meta_keys": sorted(fo.meta),
    }
    out = Path(cfg.paths.out)
    contact_sheet(fo.frames, out / "contact_sheet.png")
    write_yaml(out / "summary.yaml", summary)
    print(f"check_footage: {summary['n_frames']} frames {summary['size_px'][0]}x{summary['size_px'][1]}, "
          f"{summary['duration_s']:.3f} s, devices {sorted(fo.cameras)}")


main = stage_app("check_footage", run)

if __name__ == "__main__":
    main()
