"""Fluid benchmarks: edit optimisation on a 128x128 field, texture-transfer render per 256x256
frame. Prints the median of several runs (single thread; the machine may be shared).

Run: ``.venv/bin/python benchmarks/bench_fluid.py [--runs 3]``
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from vidsim.fluid.edit import EditSpec, RenderSettings  # noqa: E402
from vidsim.fluid.flow import estimate_flow  # noqa: E402
from vidsim.fluid.optimize import edit_field  # noqa: E402
from vidsim.fluid.render import downsample_flow, render_sequence  # noqa: E402
from vidsim.reality.fluid import make_scene  # noqa: E402

EDIT = {
    "grid": {"height": 128, "width": 128},
    "sources": [{"box": [24, 0, 104, 2], "distribution": [["l", 0.3], ["m", 0.4], ["r", 0.3]]}],
    "sinks": [{"name": "l", "box": [0, 120, 36, 128]}, {"name": "m", "box": [48, 120, 80, 128]},
              {"name": "r", "box": [92, 120, 128, 128]}],
    "obstacles": [{"center": [64.0, 64.0], "radii": [14.0, 7.0]}],
    "optimizer": {"iterations": 100},
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    a = ap.parse_args()
    foot = make_scene("waterfall", size=256, n_frames=48, seed=0)
    flow = estimate_flow(foot.frames)
    grid = downsample_flow(flow, 2)  # 128x128 nodes
    spec = EditSpec.from_dict(EDIT)
    times, fracs, its = [], [], []
    for _ in range(a.runs):
        t = time.perf_counter()
        r = edit_field(grid.mean(0), spec, grid[::8])
        times.append(time.perf_counter() - t)
        fracs.append(r.figures["fraction_in_desired_sink"])
        its.append(r.figures["iterations"])
    print(f"edit optimisation 128x128, {len(r.desired)} particles, {its[0]} iterations: "
          f"median {np.median(times):.2f} s over {a.runs} runs; fraction in desired sink {fracs[0]:.3f}")
    field = flow.mean(0)
    per = []
    for k in range(a.runs):
        _, figs = render_sequence(foot.frames, flow, field, 24, np.random.default_rng(k), RenderSettings(),
                                  match_flow=field)
        per.append(figs["time_per_frame_s"])
    print(f"render 256x256 advected, 24 frames: median {np.median(per):.3f} s/frame over {a.runs} runs "
          "(includes the first frame's full PATCHSELECT and the candidate KD-tree)")


if __name__ == "__main__":
    main()
