"""Sim-to-real gaps: reality effects switched on in MuJoCo but withheld from the estimator's model.

Exact rasterised silhouettes (no pyrender, no segmentation) isolate the effect of the physics and
lens mismatch. Each row fits one throw (single start from the 30-degree guess of the protocol).

Usage::

    python benchmarks/bench_rigid_effects.py [--seed 100]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from vidsim.reality.rigid import RigidEffects, RigidRealityConfig, make_throw  # noqa: E402
from vidsim.rigid.body import BoxBody  # noqa: E402
from vidsim.rigid.evaluate import perturbed_guess, score  # noqa: E402
from vidsim.rigid.fit import fit_throw  # noqa: E402

CASES = {
    "none": RigidEffects(),
    "drag x1": RigidEffects(drag=1.0, angular_drag=1.0),
    "drag x1 + Magnus x1": RigidEffects(drag=1.0, angular_drag=1.0, magnus=1.0),
    "wind 3 m/s (drag x1)": RigidEffects(drag=1.0, angular_drag=1.0, wind=[3.0, 0.0, 0.0]),
    "COM offset 1 cm": RigidEffects(com_offset=[0.01, 0.0, 0.0]),
    "lens k1 = -0.05": RigidEffects(lens_k1=-0.05),
    "time jitter 2 ms": RigidEffects(time_jitter=0.002),
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=100)
    a = ap.parse_args()
    for name, eff in CASES.items():
        th = make_throw(a.seed, RigidRealityConfig(n_background=3), eff, render=False)
        body = BoxBody.from_meta(th.meta["object"])
        guess = perturbed_guess(th.truth, np.random.default_rng(a.seed))
        res = fit_throw(th.masks, th.times, th.camera, body, guess, {"multistart": "none"})
        s = score(res, th.truth, body)
        print(f"{name:24s} IoU {s['mean_iou']:.3f}  rot {s['orientation_deg']:.2f} deg  w {100 * s['omega_rel']:.2f} %  "
              f"X {100 * s['position_rel_range']:.2f} %  V {100 * s['velocity_rel']:.2f} %  g {s['gravity_deg']:.2f} deg  "
              f"all criteria: {s['success']}", flush=True)


if __name__ == "__main__":
    main()
