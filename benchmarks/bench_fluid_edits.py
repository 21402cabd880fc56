"""Run the four example edits (docs/fluid_edits/*.yaml) end to end and print their measured
figures; with ``--out DIR`` also write a still strip (source | output frames 0, n/2, n-1) per
edit through the atomic writers.

Run: ``.venv/bin/python benchmarks/bench_fluid_edits.py [--frames 120] [--out results/fluid]``
The PIV recording (1024x765) is area-downsampled 4x to 256x191 for speed.
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
    a = ap.parse_args()
    for f in sorted((REPO_ROOT / "docs" / "fluid_edits").glob("*.yaml")):
        spec = EditSpec.from_dict(yaml.safe_load(f.read_text()))
        src = footage(spec.footage)
        t = time.perf_counter()
        r = run_edit(src, spec, np.random.default_rng(0), a.frames)
        figs = r["figures"]
        figs["total_s"] = time.perf_counter() - t
        print(f.stem, json.dumps(figs, default=float))
        if a.out is not None:
            o = r["frames"]
            strip = np.concatenate([src[0, :o.shape[1], :o.shape[2]], o[0], o[len(o) // 2], o[-1]], 1)
            with atomic_path(a.out / f"{f.stem}.png") as p:
                cv2.imwrite(str(p), cv2.cvtColor(strip, cv2.COLOR_RGB2BGR))
            write_json(a.out / f"{f.stem}.json", figs)


if __name__ == "__main__":
    main()
