"""How fast two runs of the cloth model part when one parameter differs by a tiny amount.

The cloth gap diagnosis (docs/gap.md) and the study's fits (docs/cloth_study.md) call the model's
swatch trajectories chaotic. This measures it: the gap suite's model (12x12, plain velocity
Verlet at its fixed step, 0.5 s settle, the suite's exp1 corner path) at the suite twin's
parameters, and the same with one estimated parameter (natural log for stiffnesses, SI for
drags) moved by ``--rel``; the largest vertex distance between the two runs at chosen frames.
With ``--steps`` the step is also scaled (0.5 = half the step): if the growth were a numerical
instability of the scheme it would change with the step; a physical sensitivity does not.

    python benchmarks/bench_cloth_divergence.py                      # every parameter, 1e-8 / 1e-5 / 1e-3
    python benchmarks/bench_cloth_divergence.py --params stretch --rel 1e-5 --steps 1 0.5 0.25 0.1
    python benchmarks/bench_cloth_divergence.py --bend 8e-5 --rel 1e-5 1e-3   # a stiff twin
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vidsim.gap.cloth_model import ClothGapModel, ClothSetup  # noqa: E402
from vidsim.gap.cloth_suite import ClothSceneConfig, make_case, mid_range_params  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", nargs="+", default=None, help="estimated parameters to move (default: all)")
    ap.add_argument("--rel", nargs="+", type=float, default=[1e-8, 1e-5, 1e-3],
                    help="moves of the parameter (its model coordinate: ln for stiffnesses)")
    ap.add_argument("--steps", nargs="+", type=float, default=[1.0], help="step factors (1: the model's own)")
    ap.add_argument("--frames", nargs="+", type=int, default=[0, 4, 8, 12, 15])
    ap.add_argument("--bend", type=float, default=None,
                    help="the twin's bending stiffness, N m (default: the suite's, 3e-6)")
    a = ap.parse_args()
    sc = ClothSceneConfig()
    if a.bend is not None:
        if not (np.isfinite(a.bend) and a.bend > 0):
            ap.error(f"--bend must be a positive number of N m, got {a.bend}")
        sc.twin_params = dict(sc.twin_params, bend=float(a.bend))
    # the suite's null case supplies the measured corner paths and the camera (the footage is unused)
    tr = make_case({"label": "none", "seed": 320}, sc).trial
    T = tr.sil.shape[0]
    est = list(sc.estimate)
    p = mid_range_params(density=tr.density).replace(**{k: float(v) for k, v in sc.twin_params.items()})
    setup = ClothSetup(tr.times, tr.corner_paths, np.arange(T), tr.camera, tr.size, tr.density,
                       sc.resolution, sc.settle_s_model, 0.0, 1, "explicit")
    dt0 = ClothGapModel(setup, p, est, ()).dt
    names = a.params or est
    print(f"bend {p.bend:g} N m; model step {dt0 * 1e6:.1f} us; largest vertex distance (mm) at frames {a.frames} "
          f"({', '.join(f'{tr.times[f]:.3f}' for f in a.frames)} s)")
    for fac in a.steps:
        m = ClothGapModel(setup, p, est, (), dt=dt0 * fac)
        th = m.theta0()
        P0, V0, ok0 = m.simulate(th)
        if not ok0:
            print(f"step x{fac}: the unperturbed run failed")
            continue
        for name in names:
            j = est.index(name)
            for rel in a.rel:
                t2 = th.copy()
                t2[j] += rel
                P1, _, ok1 = m.simulate(t2)
                d = np.linalg.norm(P1 - P0, axis=2).max(axis=1) * 1000.0
                print(f"step x{fac:<5g} {name:12s} +{rel:<7.0e}: " + "  ".join(f"{d[f]:9.4f}" for f in a.frames)
                      + ("" if ok1 else "  (perturbed run failed)"), flush=True)


if __name__ == "__main__":
    main()
