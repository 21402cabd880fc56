"""Sanity study: film the MuJoCo cloth reality with stripes and compare fabrics with the metric.

Each fabric's footage (exp1, exp2; per-face air drag on) is rendered with the project's fast
stripe renderer (``vidsim.render.projector``, a fixed illustrative camera and projector, no
sensor noise), turned into angle maps, gradient masks (tau = 0.03 rad/px) and silhouettes (the
rendered depth, not segmentation), and every fabric's footage is scored against every other
fabric's with :func:`vidsim.video.anglemap.cloth_metric` (alpha = 0.1, mean per frame). The
diagonal is zero by construction; the off-diagonal says how far apart the fabrics are for the
metric. Prints timings too (shared machine: expect jitter).

Run: ``.venv/bin/python benchmarks/cloth_reality_metric_matrix.py``
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from vidsim.reality.cloth import fabric_profile, simulate_swatch, swatch_motion
from vidsim.render.projector import Projector, render_stripes_batch
from vidsim.video.anglemap import angle_map, cloth_metric
from vidsim.video.camera import PinholeCamera, intrinsics, look_at

NAMES = ["linen", "fleece", "satin", "knit"]


def main(tau: float = 0.03) -> None:
    cv2.setNumThreads(1)
    R, t = look_at(np.array([0.0, -1.3, 0.9]), np.array([0.0, 0.0, 0.85]))
    cam = PinholeCamera(intrinsics(330, None, 159.5, 119.5), R, t, 320, 240)
    Rp, tp = look_at(np.array([0.35, -1.2, 1.15]), np.array([0.0, 0.0, 0.85]))
    proj = Projector(PinholeCamera(intrinsics(800, None, 399.5, 299.5), Rp, tp, 800, 600), period_px=12.0)
    for mot in ("exp1", "exp2"):
        feat = {}
        for fab in NAMES:
            run = simulate_swatch(fabric_profile(fab), swatch_motion(mot), {"air_drag": {"on": True}},
                                  np.random.default_rng(0))
            t0 = time.perf_counter()
            imgs, depth = render_stripes_batch(run.vertices, run.faces, cam, proj)
            t1 = time.perf_counter()
            sil = np.isfinite(depth)
            ams = [angle_map(imgs[i], region=sil[i]) for i in range(len(imgs))]
            t2 = time.perf_counter()
            feat[fab] = (np.array([a.theta for a in ams]), np.array([a.mask(tau) for a in ams]), sil)
            print(f"{mot} {fab:7s} MuJoCo {run.truth['wall_time_s']:.2f} s, render 50 frames {t1 - t0:.2f} s, "
                  f"angle maps {t2 - t1:.2f} s, silhouette {sil.sum((1, 2)).mean():.0f} px/frame, "
                  f"fold mask {feat[fab][1].sum((1, 2)).mean():.0f} px/frame")
        print(f"E (rad^2 + 0.1 px, per frame), rows = footage, columns = simulated fabric, {mot}")
        print("         " + " ".join(f"{n:>8s}" for n in NAMES))
        for a in NAMES:
            tr, mr, sr = feat[a]
            row = [cloth_metric(tr, mr, sr, feat[b][0], feat[b][2])[0] for b in NAMES]
            print(f"{a:8s} " + " ".join(f"{x:8.1f}" for x in row))


if __name__ == "__main__":
    main()
