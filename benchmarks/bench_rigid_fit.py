"""Wall time of one throw's whole estimation (segmentation + all multi-start fits), median of runs.

Usage::

    python benchmarks/bench_rigid_fit.py [--runs 3] [--seed 100] [--orient 90]

The throw is rendered once (pyrender, not timed); each run segments the footage and fits from a
guess ``--orient`` degrees off (other parameters off as in the recovery protocol), single thread.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from vidsim.reality.rigid import make_throw  # noqa: E402
from vidsim.rigid.body import BoxBody  # noqa: E402
from vidsim.rigid.evaluate import perturbed_guess  # noqa: E402
from vidsim.rigid.fit import SilhouetteObjective, fit_throw  # noqa: E402
from vidsim.video.segment import segment  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--orient", type=float, default=90.0)
    a = ap.parse_args()
    cv2.setNumThreads(1)
    th = make_throw(a.seed)
    body = BoxBody.from_meta(th.meta["object"])
    guess = perturbed_guess(th.truth, np.random.default_rng(a.seed), orient_deg=a.orient)
    fit_throw(th.masks, th.times, th.camera, body, guess, {"multistart": "none"})  # compile numba caches
    seg_t, fit_t, evals = [], [], []
    for _ in range(a.runs):
        t = time.perf_counter()
        masks = segment(th.frames)
        seg_t.append(time.perf_counter() - t)
        res = fit_throw(masks, th.times, th.camera, body, guess)
        fit_t.append(res.seconds)
    # one objective evaluation (value + hybrid gradient) per pyramid level, all 40 frames
    p = res.params.copy()
    for scale in (0.25, 0.5, 1.0):
        obj = SilhouetteObjective(body, th.camera, res.times, masks[res.frames], res.t0, scale)
        obj(p, res.q0)
        ts = []
        for _ in range(20):
            t = time.perf_counter()
            obj(p, res.q0)
            ts.append(time.perf_counter() - t)
        evals.append((scale, 1e3 * float(np.median(ts))))
    print(f"segmentation (70 frames 640x480): median {np.median(seg_t):.2f} s over {a.runs} runs")
    print(f"fit, all {res.n_starts} starts: median {np.median(fit_t):.1f} s over {a.runs} runs "
          f"(min {min(fit_t):.1f}, max {max(fit_t):.1f}); mean IoU {res.mean_iou:.3f}")
    print(f"whole estimation (segment + fit): median {np.median(np.add(seg_t, fit_t)):.1f} s")
    for scale, ms in evals:
        print(f"objective + hybrid gradient, 40 frames, scale {scale}: median {ms:.1f} ms")


if __name__ == "__main__":
    main()
