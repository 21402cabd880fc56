"""Fluid benchmarks: optical flow on the real Middlebury scenes against OpenCV's DIS medium,
the seed's Figure 15 layout (plain vs harmonic initialisation), edit optimisation on a 128x128
field, texture-transfer render per 256x256 frame. Prints the median of several runs, wall-clock
and CPU time of this process (single thread; on a shared machine the CPU time is the figure
that does not count other jobs).

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


# the seed's Figure 15 layout: one source split between two sinks low left and low right, a
# continuous descent from a field leaning left strands half the particles in the wrong sink
FIG15 = {
    "grid": {"height": 64, "width": 64},
    "sources": [{"name": "top", "box": [20, 4, 44, 5], "distribution": [["red", 0.5], ["green", 0.5]]}],
    "sinks": [{"name": "red", "box": [4, 56, 22, 60]}, {"name": "green", "box": [42, 56, 60, 60]}],
    "weights": {"flow": 1.0, "smooth": 0.2, "neighborhood": 0.2},
    "optimizer": {"iterations": 200},
}


def middlebury() -> None:
    """Average endpoint error on the real Middlebury scenes: ours (DIS fine) vs OpenCV DIS medium."""
    import cv2

    from vidsim.fluid.flow import endpoint_error, flow_pair, parse_flo
    from vidsim.io.paths import shared_data_dir

    for scene in ("RubberWhale", "Dimetrodon"):
        d = shared_data_dir() / "middlebury_flow" / scene
        if not d.is_dir():
            print(f"middlebury {scene}: {d} is absent, skipped")
            continue
        a, b = (cv2.cvtColor(cv2.imread(str(d / f)), cv2.COLOR_BGR2RGB) for f in ("frame10.png", "frame11.png"))
        gt = parse_flo((d / "flow10.flo").read_bytes())
        ours, ref = (endpoint_error(flow_pair(a, b, m), gt) for m in ("dis_fine", "dis_medium"))
        print(f"middlebury {scene}: EPE dis_fine {ours:.3f} px, OpenCV DIS medium {ref:.3f} px; target no worse: "
              f"{'met' if ours <= ref else 'NOT met'}")


def figure15(flow: np.ndarray) -> None:
    """The Figure 15 layout on the waterfall's (downward) video field, 64x64 nodes: plain
    descent from a left-leaning uniform field vs the default harmonic initialisation."""
    grid = downsample_flow(flow, 4)
    for init in ({"init": "uniform", "uniform": [-0.5, 1.0]}, {"init": "harmonic"}):
        d = {**FIG15, "optimizer": {**FIG15["optimizer"], **init}}
        r = edit_field(grid.mean(0), EditSpec.from_dict(d), grid[::8])
        print(f"figure 15 layout, init {init['init']}: {100 * r.figures['fraction_in_desired_sink']:.1f} % of "
              f"{len(r.desired)} particles in their desired sink (at initialisation "
              f"{100 * r.figures['fraction_in_desired_sink_init']:.1f} %); target >= 98 %")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    a = ap.parse_args()
    middlebury()
    foot = make_scene("waterfall", size=256, n_frames=48, seed=0)
    flow = estimate_flow(foot.frames)
    figure15(flow)
    grid = downsample_flow(flow, 2)  # 128x128 nodes
    spec = EditSpec.from_dict(EDIT)
    times, cpu, fracs, its = [], [], [], []
    for _ in range(a.runs):
        t, c = time.perf_counter(), time.process_time()
        r = edit_field(grid.mean(0), spec, grid[::8])
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
        fracs.append(r.figures["fraction_in_desired_sink"])
        its.append(r.figures["iterations"])
    print(f"edit optimisation 128x128, {len(r.desired)} particles, {its[0]} iterations: "
          f"median {np.median(times):.2f} s wall, {np.median(cpu):.2f} s CPU over {a.runs} runs; "
          f"fraction in desired sink {fracs[0]:.3f}")
    field = flow.mean(0)
    per, per_cpu = [], []
    for k in range(a.runs):
        c = time.process_time()
        _, figs = render_sequence(foot.frames, flow, field, 24, np.random.default_rng(k), RenderSettings(),
                                  match_flow=field)
        per.append(figs["time_per_frame_s"])
        per_cpu.append((time.process_time() - c) / 24)
    print(f"render 256x256 advected, 24 frames: median {np.median(per):.3f} s/frame wall, {np.median(per_cpu):.3f} "
          f"s/frame CPU over {a.runs} runs (includes the first frame's full PATCHSELECT and the candidate KD-tree); "
          f"target <= 1 s/frame: {'met' if np.median(per_cpu) <= 1.0 else 'NOT met'}")


if __name__ == "__main__":
    main()
