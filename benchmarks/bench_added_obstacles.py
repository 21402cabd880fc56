"""Obstacles the edit adds, drawn from patches (``render.added_obstacles: patches``, the renderer
before the transplant, bit-identical to it until the hole filler covered the overlaps between
cells, 5 Dec 2026) and transplanted (``transplant``, the default), on
the example edits that add one beside an ``in_footage`` obstacle (``piv_karman_second_cylinder``,
``stream_second_boat``).

Per edit, mode and render seed (``run_edit`` as ``bench_fluid_edits.py`` runs it):

* grey (mean of R, G, B) inside the added obstacle, mean and standard deviation over all output
  pixels and frames, on its pixel mask and 2 px in from its edge; the same inside the
  ``in_footage`` obstacle it is drawn from, in the source frames. The transplant shows that
  obstacle's temporal median, so its mean agrees by construction (to the resampling and the
  mask's rim) and its standard deviation lacks the camera noise: these say the transplant is
  wired in, not that it is good;
* outline contrast: around the obstacle's centroid, 24 angular sectors; per sector the mean grey
  1-4 px outside the mask minus 1-4 px inside it (time-mean image); its mean, and the share of
  sectors whose contrast has the source obstacle's sign and at least half its mean magnitude
  ("outline visible"), beside the same for the source obstacle in the source. Also by
  construction for the transplant (its edge is the source obstacle's edge, rescaled); the
  comparison with patches is the point;
* the whole-frame figures of ``bench_fluid_edits.py``: patch ratio, detail ratio,
  motion-compensated flicker, rendered-flow EPE relative to the field's speed, and the bare
  pixels (no patch covers them and they show the patches, summed over the frames; 0 by
  construction since the hole filler's last pass covers them: a check), the same count before
  that pass, and the patches the pass spawned on such pixels.

Run: ``.venv/bin/python benchmarks/bench_added_obstacles.py [--seeds 0 1 2] [--frames 120]
[--png DIR]`` (about 10 s per edit, mode and seed); ``--png`` writes, per edit, source | patches |
transplant at the middle output frame of the first seed (2x, nearest neighbour).
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402

from bench_fluid_edits import footage  # noqa: E402
from vidsim.fluid.edit import EditSpec  # noqa: E402
from vidsim.fluid.pipeline import run_edit  # noqa: E402
from vidsim.io.atomic import atomic_path  # noqa: E402
from vidsim.io.paths import REPO_ROOT  # noqa: E402

EDITS = ("piv_karman_second_cylinder", "stream_second_boat")
MODES = ("patches", "transplant")


def pixel_mask(node_mask: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Node mask to the output's pixels, as ``run_edit`` rasterises obstacles."""
    return cv2.resize(node_mask.astype(np.uint8), (size[1], size[0]), interpolation=cv2.INTER_NEAREST).astype(bool)


def sector_contrast(grey: np.ndarray, mask: np.ndarray, sectors: int = 24, band: float = 4.0) -> np.ndarray:
    """Per angular sector around the mask's centroid: mean of ``grey`` (H, W) 1..``band`` px outside
    the mask minus 1..``band`` px inside it (NaN where a sector has no such pixel)."""
    d_in = cv2.distanceTransform(mask.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    d_out = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    inner, outer = mask & (d_in >= 1) & (d_in <= band), ~mask & (d_out >= 1) & (d_out <= band)
    cy, cx = np.argwhere(mask).mean(0)
    yy, xx = np.mgrid[0:mask.shape[0], 0:mask.shape[1]]
    sec = ((np.arctan2(yy - cy, xx - cx) + np.pi) / (2 * np.pi) * sectors).astype(int) % sectors
    out = np.full(sectors, np.nan)
    for k in range(sectors):
        i, o = inner & (sec == k), outer & (sec == k)
        if i.any() and o.any():
            out[k] = grey[o].mean() - grey[i].mean()
    return out


def obstacle_figures(frames: np.ndarray, mask: np.ndarray) -> dict[str, float]:
    """Grey inside ``mask`` (whole and 2 px in) over all ``frames``, and its outline contrast."""
    g = frames.astype(np.float64).mean(-1)
    core = cv2.erode(mask.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    c = sector_contrast(g.mean(0), mask)
    return {"grey_mean": float(g[:, mask].mean()), "grey_std": float(g[:, mask].std()),
            "grey_mean_2px_in": float(g[:, core].mean()), "grey_std_2px_in": float(g[:, core].std()),
            "contrast_mean": float(np.nanmean(c)), "contrast_sectors": c}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--png", type=Path, default=None)
    a = ap.parse_args()
    for name in EDITS:
        d = yaml.safe_load((REPO_ROOT / "docs" / "fluid_edits" / f"{name}.yaml").read_text())
        spec0 = EditSpec.from_dict(d)
        src = footage(spec0.footage)
        H, W = spec0.height * spec0.downsample, spec0.width * spec0.downsample
        picks = spec0.transplant_sources()
        i_add = next(i for i, j in enumerate(picks) if j is not None)
        added = pixel_mask(spec0.obstacles[i_add].mask(spec0.height, spec0.width), (H, W))
        shown = pixel_mask(spec0.obstacles[picks[i_add]].mask(spec0.height, spec0.width), (H, W))
        ref = obstacle_figures(src[:, :H, :W], shown)
        sign, mag = np.sign(ref["contrast_mean"]), abs(ref["contrast_mean"])

        def visible(c: np.ndarray) -> float:
            return float(np.mean(sign * c >= 0.5 * mag))
        print(f"{name}: source obstacle {picks[i_add]} in the source: grey {ref['grey_mean']:.2f} +- {ref['grey_std']:.2f} "
              f"(2 px in {ref['grey_mean_2px_in']:.2f} +- {ref['grey_std_2px_in']:.2f}), outline contrast "
              f"{ref['contrast_mean']:.2f}, visible in {visible(ref['contrast_sectors']):.3f} of the sectors; "
              f"the source at the added obstacle's place: grey {src[:, :H, :W][:, added].mean():.2f}", flush=True)
        mid = {}
        for mode in MODES:
            rows = []
            for seed in a.seeds:
                d["render"] = {**(d.get("render") or {}), "added_obstacles": mode}
                r = run_edit(src, EditSpec.from_dict(d), np.random.default_rng(seed), a.frames)
                f, o = r["figures"], obstacle_figures(r["frames"], added)
                row = {"grey_mean": o["grey_mean"], "grey_std": o["grey_std"], "grey_mean_2px_in": o["grey_mean_2px_in"],
                       "grey_std_2px_in": o["grey_std_2px_in"], "contrast_mean": o["contrast_mean"],
                       "outline_visible": visible(o["contrast_sectors"]), "patch_ratio": f["patch_distance"]["ratio"],
                       "detail_ratio": f["detail_ratio"], "flicker_mc": f["flicker_mc_output"],
                       "epe_rel": f["rendered_flow_epe_rel"], "bare_pixels": f["render"]["bare_pixels"],
                       "bare_before_last_pass": f["render"]["bare_before_last_pass"],
                       "spawned_on_bare": f["render"]["spawned_on_bare"]}
                rows.append(row)
                print(f"{name} {mode} seed {seed}: " + json.dumps({k: round(v, 4) for k, v in row.items()}), flush=True)
                if seed == a.seeds[0]:
                    mid[mode] = r["frames"][len(r["frames"]) // 2]
            print(f"{name} {mode} mean of {len(rows)} seeds: " + ", ".join(
                f"{k} {np.mean([x[k] for x in rows]):.3f}" for k in rows[0]), flush=True)
        if a.png is not None:
            n = a.frames // 2
            row = np.concatenate([src[n % len(src), :H, :W], mid["patches"], mid["transplant"]], 1)
            with atomic_path(a.png / f"{name}_added_obstacle.png") as p:
                cv2.imwrite(str(p), cv2.cvtColor(cv2.resize(row, None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST),
                                                 cv2.COLOR_RGB2BGR))


if __name__ == "__main__":
    main()
