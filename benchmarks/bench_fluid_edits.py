"""Run the four example edits (docs/fluid_edits/*.yaml) end to end and print their measured
figures; with ``--out DIR`` also write a still strip (source | output frames 0, n/2, n-1) per
edit through the atomic writers.

Run: ``.venv/bin/python benchmarks/bench_fluid_edits.py [--frames 120] [--out results/fluid]
[--only NAME ...] [--render KEY=VALUE ...]``; ``--render`` overrides the edits' ``render:``
settings (e.g. ``--render velocity_noise=0 usage=0 resample=linear`` for the K-nearest
PATCHSELECT of before, see docs/fluid_editing.md). The PIV recording (1024x765) is
area-downsampled 4x to 256x191 for speed. The last line per edit lists the issue-8 targets.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402

from vidsim.fluid.edit import EditSpec  # noqa: E402
from vidsim.fluid.pipeline import prepare_gray_frames, run_edit  # noqa: E402
from vidsim.io.atomic import atomic_path, write_json  # noqa: E402
from vidsim.io.paths import REPO_ROOT, shared_data_dir  # noqa: E402
from vidsim.reality.fluid import make_scene  # noqa: E402


def footage(name: str) -> np.ndarray:
    if name.startswith("synthetic:"):
        return make_scene(name.split(":", 1)[1], size=128, n_frames=120, seed=0).frames
    if name == "piv:karman":
        d = shared_data_dir() / "pivlab_karman"
        return prepare_gray_frames([cv2.imread(str(d / f"PIVlab_Karman_0{i}.bmp"), cv2.IMREAD_GRAYSCALE)
                                    for i in range(1, 5)], downsample=4)
    raise ValueError(f"footage={name!r}: unknown")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--only", nargs="*", default=None, help="edit names (default: all)")
    ap.add_argument("--render", nargs="*", default=[], help="render overrides KEY=VALUE (YAML values)")
    a = ap.parse_args()
    over = {k: yaml.safe_load(v) for k, v in (kv.split("=", 1) for kv in a.render)}
    for f in sorted((REPO_ROOT / "docs" / "fluid_edits").glob("*.yaml")):
        if a.only and f.stem not in a.only:
            continue
        d = yaml.safe_load(f.read_text())
        d["render"] = {**(d.get("render") or {}), **over}
        spec = EditSpec.from_dict(d)
        src = footage(spec.footage)
        t, c = time.perf_counter(), time.process_time()
        r = run_edit(src, spec, np.random.default_rng(0), a.frames)
        figs = r["figures"]
        figs["total_s"], figs["total_cpu_s"] = time.perf_counter() - t, time.process_time() - c
        print(f.stem, json.dumps(figs, default=float))
        fo, fs = figs["flicker_output"], figs["flicker_source"]
        print(f"{f.stem}: in desired sink {figs['edit']['fraction_in_desired_sink']:.3f} (>= 0.98); rendered-flow EPE "
              f"{figs['rendered_flow_epe_px']:.3f} px/frame = {figs['rendered_flow_epe_rel']:.3f} x the field's mean speed "
              f"there (<= 0.5; speed {figs['edited_speed_epe_mask_px']:.3f}); patch ratio {figs['patch_distance']['ratio']:.3f} (<= 1.5; coherence "
              f"{figs['patch_distance']['coherence_ratio']:.3f}, completeness {figs['patch_distance']['completeness_ratio']:.3f}); "
              f"detail ratio {figs['detail_ratio']:.3f} (>= 0.8); static flicker {fo:.3f} (<= source {fs:.3f}; nan = no static region "
              f"of >= 100 px); compensated flicker {figs['flicker_mc_output']:.3f} (source {figs['flicker_mc_source']:.3f}); "
              f"bare pixels {figs['render']['bare_pixels']} (0 by construction; before the hole filler's last pass "
              f"{figs['render']['bare_before_last_pass']}, patches it spawned {figs['render']['spawned_on_bare']}); "
              f"render {figs['render']['time_per_frame_s']:.3f} s/frame; total {figs['total_s']:.1f} s wall, "
              f"{figs['total_cpu_s']:.1f} s CPU", flush=True)
        if a.out is not None:
            o = r["frames"]
            strip = np.concatenate([src[0, :o.shape[1], :o.shape[2]], o[0], o[len(o) // 2], o[-1]], 1)
            with atomic_path(a.out / f"{f.stem}.png") as p:
                cv2.imwrite(str(p), cv2.cvtColor(strip, cv2.COLOR_RGB2BGR))
            write_json(a.out / f"{f.stem}.json", figs)


if __name__ == "__main__":
    main()
