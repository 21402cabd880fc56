"""Benchmark: one cloth objective evaluation (simulate, render stripes, angle maps, metric).

50 frames of a 20x20 swatch at 320x240 against MuJoCo linen footage (exp1), at three
parameter sets (stiff / mid / soft: the simulator's stable step depends on stiffness).
Prints the median of ``--repeat`` runs and the breakdown by part. Single process, one core.

    .venv/bin/python benchmarks/bench_clothfit.py --repeat 3
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import cv2
import numpy as np
from omegaconf import OmegaConf

from vidsim.cloth import ClothParams
from vidsim.clothfit.features import FeatureSettings, extract_features
from vidsim.clothfit.film import FilmSettings, film_cloth
from vidsim.clothfit.objective import ClothObjective, ModelSettings, Trial, space_from_config
from vidsim.config import camera_from_config, projector_from_config
from vidsim.config.cloth import ClothConfig, ClothModelConfig
from vidsim.reality.cloth import fabric_profile, simulate_swatch, swatch_motion
from vidsim.render.projector import Projector


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--resolution", type=int, default=20)
    ap.add_argument("--frames", type=int, default=50)
    ap.add_argument("--multirate", default=ClothModelConfig().multirate,
                    help="cloth.model.multirate: bending kicked once per that many steps, or 'auto' "
                         "(default: the config's)")
    ap.add_argument("--damping", default=ClothModelConfig().damping, choices=["explicit", "split", "auto"],
                    help="cloth.model.damping (default: the config's)")
    a = ap.parse_args()
    cv2.setNumThreads(1)
    cfg = OmegaConf.structured(ClothConfig())
    cam = camera_from_config(cfg.camera)
    pc = projector_from_config(cfg.projector)
    proj = Projector(pc, period_px=cfg.projector.period_px, power=cfg.projector.power, ambient=cfg.projector.ambient)
    run = simulate_swatch(fabric_profile("linen"), swatch_motion("exp1"), {"air_drag": {"on": True}}, np.random.default_rng(0),
                         n_frames=a.frames)
    frames = film_cloth(run.vertices, run.faces, cam, proj, np.random.default_rng(1), FilmSettings())
    fs = FeatureSettings()
    feat = extract_features(frames, np.arange(5), fs)
    tr = Trial("linen/exp1", feat, run.times, run.corner_paths_measured, cam, proj, 0.3, 0.2)
    obj = ClothObjective([tr], space_from_config(dict(cfg.fit.space)),
                         model=ModelSettings(resolution=a.resolution, multirate=str(a.multirate), damping=a.damping),
                         features=fs)
    sets = {"stiff (linen-like)": ClothParams(stretch=3000, shear=500, bend=4e-5),
            "mid": ClothParams(stretch=300, shear=50, bend=1e-5),
            "soft": ClothParams(stretch=30, shear=5, bend=4e-7)}
    obj.evaluate(obj.theta_of(sets["mid"]))  # numba compile / cache load
    print(f"cloth objective: {a.frames} frames, {a.resolution}x{a.resolution} swatch, {cam.width}x{cam.height}, "
          f"multirate {a.multirate}, damping {a.damping}, median of {a.repeat} (wall s, and CPU s of the whole evaluation)")
    for name, p in sets.items():
        rows = []
        for _ in range(a.repeat):
            t, c = time.perf_counter(), time.process_time()
            r = obj.evaluate(obj.theta_of(p))
            rows.append([time.perf_counter() - t, time.process_time() - c]
                        + [r.timing[k] for k in ("simulate", "render", "anglemap", "metric")])
        m = np.median(np.array(rows), axis=0)
        print(f"  {name:18s} total {m[0]:.3f} (CPU {m[1]:.3f})  simulate {m[2]:.3f}  render {m[3]:.3f}  "
              f"anglemap {m[4]:.3f}  metric {m[5]:.3f}  (E = {r.score:.1f})")
    print(f"load average {os.getloadavg()[0]:.1f} (2 cores: parts are wall times, inflated by the load)")


if __name__ == "__main__":
    main()
