"""Is the settled swatch planar? The estimator's model against the MuJoCo reality, at frame 0.

The swatch hangs from its two top corners in the x-z plane (y normal) and is held still before the
filmed motion starts. The estimator's model settles *exactly* planar (no force has a y component
until the corners move), a symmetric equilibrium that any out-of-plane push breaks on a soft
fabric (docs/gap.md, "Why the wind refits do not move"); the reality engine may settle buckled.
Prints the out-of-plane deviation |y - the corners' y| at frames 0, 3, 9 for each fabric's
reality (exp1 motion, air on) and the model's frame 0 at the fabric's own stiffnesses.

    .venv/bin/python benchmarks/cloth_settle_planarity.py
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

from vidsim.cloth import ClothParams, simulate
from vidsim.clothfit.film import swatch_driver, swatch_model_mesh
from vidsim.clothfit.objective import ModelSettings
from vidsim.reality.cloth import fabric_profile, simulate_swatch, swatch_motion


def main() -> None:
    ms = ModelSettings()
    print("out-of-plane deviation |y - corners' y| [mm]: max / rms")
    for fab in ("linen", "fleece", "satin", "knit"):
        prof = fabric_profile(fab)
        run = simulate_swatch(prof, swatch_motion("exp1"), {"air_drag": {"on": True}}, np.random.default_rng(0), n_frames=10)
        cells = []
        for f in (0, 3, 9):
            d = run.vertices[f][:, 1] - run.corner_paths_measured[f][:, 1].mean()
            cells.append(f"frame {f}: {1e3 * np.abs(d).max():6.2f} / {1e3 * np.sqrt(np.mean(d * d)):5.2f}")
        mesh = swatch_model_mesh(run.corner_paths_measured[0], ms.resolution, 0.3)  # simulate_swatch's default size
        drv, t0 = swatch_driver(mesh, run.times, run.corner_paths_measured, ms.settle_s)
        # the reality's stiffnesses (shear from its Poisson ratio); any set settles planar: no force has a y part
        p = ClothParams(bend=prof["bend"], stretch=prof["stretch"], shear=prof["stretch"] / (2 * (1 + prof["poisson"])),
                        density=prof["areal_density"])
        res = simulate(mesh, p, drv, run.times[:1], integrator="fast", t0=t0)
        y = res.positions[0][:, 1] - run.corner_paths_measured[0][:, 1].mean()
        print(f"{fab:7s} reality {'; '.join(cells)} | model at frame 0: {1e3 * np.abs(y).max():.4f} / "
              f"{1e3 * np.sqrt(np.mean(y * y)):.4f}")


if __name__ == "__main__":
    main()
