"""Benchmark: MuJoCo wall time of the cloth reality, per trial (median of ``--repeats`` runs).

Swatch: 4 fabrics x (exp1, exp2, robot), 15 x 15 vertices, 50 frames at 30 Hz after 1 s of
settling, dt = 2 ms, per-face air drag on. Skirt: 4 fabrics, 9 x 28 vertices, 50 frames.

Run: ``.venv/bin/python benchmarks/bench_cloth_reality.py [--repeats 1] [--quick]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from vidsim.reality.cloth import (
    FABRICS,
    fabric_profile,
    simulate_skirt,
    simulate_swatch,
    skirt_motion,
    swatch_motion,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--quick", action="store_true", help="one fabric, exp1 and the skirt only")
    args = ap.parse_args()
    fabrics = ["satin"] if args.quick else list(FABRICS)
    motions = ["exp1"] if args.quick else ["exp1", "exp2", "robot"]
    eff = {"air_drag": {"on": True}}
    print(f"{'trial':22s} {'frames':>6s} {'MuJoCo wall s (median)':>24s} {'min':>6s}  ok")
    t_all = time.perf_counter()
    for fab in fabrics:
        for mot in motions:
            walls, ok = [], True
            for _ in range(args.repeats):
                run = simulate_swatch(fabric_profile(fab), swatch_motion(mot), eff, np.random.default_rng(0))
                walls.append(run.truth["wall_time_s"])
                ok &= run.ok
            print(f"swatch {fab:7s} {mot:6s}   {len(run.times):6d} {np.median(walls):24.2f} {np.min(walls):6.2f}  {ok}")
        walls, ok = [], True
        for _ in range(args.repeats):
            run = simulate_skirt(fabric_profile(fab), skirt_motion(), eff, np.random.default_rng(0))
            walls.append(run.truth["wall_time_s"])
            ok &= run.ok
        pen = run.truth["max_leg_penetration_m"].max()
        print(f"skirt  {fab:7s} skip     {len(run.times):6d} {np.median(walls):24.2f} {np.min(walls):6.2f}  {ok}"
              f"  (max leg penetration {100 * pen:.1f} cm)")
    print(f"total wall (incl. model build) {time.perf_counter() - t_all:.1f} s")


if __name__ == "__main__":
    main()
