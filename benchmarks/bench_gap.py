"""Cost of the rigid gap diagnosis: one model render, one library Jacobian, one whole diagnosis.

A 40-frame 640x480 throw (exact rasterised silhouettes, lens k1 = -0.05 withheld), fitted once;
then the median of ``--repeat`` runs of: a render of all frames by the extended model at the
diagnosis scale (0.5), the Jacobian of the full candidate library on all frames, and (once) a
whole blind diagnosis.

Usage::

    python benchmarks/bench_gap.py [--repeat 5] [--full]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from vidsim.gap.rigid_diagnose import DiagnoseConfig, Problem, diagnose_rigid  # noqa: E402
from vidsim.gap.rigid_model import RIGID_EFFECTS, RigidGapModel  # noqa: E402
from vidsim.reality.rigid import RigidEffects, RigidRealityConfig, make_throw  # noqa: E402
from vidsim.rigid.body import BoxBody  # noqa: E402
from vidsim.rigid.evaluate import perturbed_guess  # noqa: E402
from vidsim.rigid.fit import fit_throw, visible_frames  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--full", action="store_true", help="also time one whole diagnosis")
    a = ap.parse_args()
    cv2.setNumThreads(1)
    th = make_throw(203, RigidRealityConfig(n_background=3), RigidEffects(lens_k1=-0.05), render=False)
    body = BoxBody.from_meta(th.meta["object"])
    res = fit_throw(th.masks, th.times, th.camera, body, perturbed_guess(th.truth, np.random.default_rng(1)),
                    {"multistart": "none"})
    fit = res.summary()
    fr = visible_frames(th.masks)
    p0 = np.r_[fit["position"], [0, 0, 0], fit["velocity"], fit["omega_world"], fit["tilt"], fit["roll"]]
    m = RigidGapModel(body, th.camera, th.times[fr], fit["t0"], np.asarray(fit["quaternion"]), list(RIGID_EFFECTS))
    theta = np.r_[p0, np.zeros(m.n_params - 14)]
    obs = np.stack([cv2.resize(x.astype(np.float32), (m.cam.width, m.cam.height), interpolation=cv2.INTER_AREA)
                    for x in th.masks[fr]])
    prob = Problem(m, obs, np.ones_like(obs, bool), np.arange(len(fr)))
    m.render(theta)
    t_r, t_j = [], []
    for _ in range(a.repeat):
        t = time.perf_counter()
        m.render(theta)
        t_r.append(time.perf_counter() - t)
    for _ in range(max(1, a.repeat // 2)):
        t = time.perf_counter()
        prob.jacobian(theta)
        t_j.append(time.perf_counter() - t)
    print(f"render {len(fr)} frames at 320x240: median {1e3 * np.median(t_r):.1f} ms; Jacobian of the base + "
          f"{len(RIGID_EFFECTS)} candidates ({m.n_params} columns): median {np.median(t_j):.2f} s")
    if a.full:
        t = time.perf_counter()
        d = diagnose_rigid(th.masks, th.times, th.camera, body, fit, DiagnoseConfig())
        print(f"whole diagnosis: {time.perf_counter() - t:.1f} s, {d.n_renders} renders; verdict: {d.verdict}")


if __name__ == "__main__":
    main()
