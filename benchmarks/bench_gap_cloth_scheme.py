"""The cloth gap diagnosis under different integration schemes of its own model.

One withheld-effect case of the cloth suite (default: the slow test's 12 ms frame-time offset,
seed 304, reduced scene of 16 frames, the grips pass alone with the grip candidates, top 1) is
filmed, fitted by the suite's reduced fit and diagnosed blind once per scheme
(``gap.cloth.diagnose.multirate`` / ``damping``); truth is read only by the scoring. Prints, per
scheme, the resolved multirate factor and damping mode, the verdict, the named effect's closure
and strength error, and the CPU seconds of the whole case (reality + fit + diagnosis).

Usage::

    python benchmarks/bench_gap_cloth_scheme.py [--schemes 1/explicit 2/explicit 4/explicit auto/auto]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from vidsim.gap.cloth_diagnose import GRIP_EFFECTS, ClothDiagnoseConfig  # noqa: E402
from vidsim.gap.cloth_suite import ClothSceneConfig, run_case  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--schemes", nargs="+", default=["1/explicit", "2/explicit", "4/explicit", "auto/auto"],
                    help="multirate/damping pairs of the diagnosis's model")
    ap.add_argument("--offset", type=float, default=0.012, help="withheld frame-time offset, seconds")
    ap.add_argument("--seed", type=int, default=304)
    a = ap.parse_args()
    scene = ClothSceneConfig(n_frames=16, frame_stride=1, budget=30, grid_levels=3)
    case = {"label": "time_offset", "seed": a.seed, "effects": {"time_offset": a.offset}}
    print("scheme | r | damping | verdict | closure | strength error | CPU-s")
    for s in a.schemes:
        mr, _, dm = s.partition("/")
        cfg = ClothDiagnoseConfig(region="grips", candidates=list(GRIP_EFFECTS), top_k=1, pairs=False,
                                  metric_terms=False, multirate=mr, damping=dm or "explicit")
        t = time.process_time()
        diag, score, _ = run_case(case, scene, cfg)
        cpu = time.process_time() - t
        model = diag.extra.get("model", {})
        clo = score.get("closure", {}).get("time_offset")
        rec = score.get("recovery", {}).get("time_offset", {}).get("rel_error")
        print(f"{s} | {model.get('multirate')} | {model.get('damping')} | {diag.verdict} | "
              f"{'-' if clo is None else f'{clo:.2f}'} | {'-' if rec is None else f'{100 * rec:.1f} %'} | {cpu:.0f}",
              flush=True)


if __name__ == "__main__":
    main()
