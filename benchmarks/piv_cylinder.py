"""Measure the cylinder of the PIVlab Karman recording, for the obstacle that
``docs/fluid_edits/piv_karman_second_cylinder.yaml`` declares.

The cylinder is the dark disc of the recording (no particles, grey ~7 against a median ~30).
Mean of the four 1024x765 frames, Gaussian blur sigma 1.5 px; from the darkest point of a
sigma-6 blur, 360 rays; on each the first point where the grey level crosses the midpoint of
the disc's level and the frame median; a least-squares (Kasa) circle through them, refitted
without the worst 20 % of points (where the laser-sheet shadow leaves the disc), three rounds
from the new centre. Prints the circle in frame pixels and in edit-grid nodes (the edit
downsamples 4x to 256x191 and has 2 px per node: node = (x + 0.5) / 8 - 0.5).

Run: ``.venv/bin/python benchmarks/piv_cylinder.py`` (needs the shared data, 2 s).
"""

from __future__ import annotations

import cv2
import numpy as np

from vidsim.io.paths import shared_data_dir

PX_PER_NODE = 8  # 4x area downsampling, then downsample: 2 in the edit


def fit_dark_disc(mean_image: np.ndarray, rounds: int = 3) -> tuple[float, float, float, dict[str, float]]:
    """``(cx, cy, r, levels)`` in pixels of the image (x = column, pixel centres at integers)."""
    m = mean_image.astype(np.float32)
    coarse = cv2.GaussianBlur(m, (0, 0), 6)
    b = cv2.GaussianBlur(m, (0, 0), 1.5)
    inside, outside = float(np.median(b[coarse < 8])), float(np.median(b))
    thr = 0.5 * (inside + outside)
    y0, x0 = np.unravel_index(np.argmin(coarse), m.shape)
    cx, cy, r = float(x0), float(y0), 0.0
    rs = np.arange(5, 120, 0.25, dtype=np.float32)
    for _ in range(rounds):
        pts = []
        for a in np.linspace(0, 2 * np.pi, 360, endpoint=False):
            xs, ys = cx + rs * np.cos(a), cy + rs * np.sin(a)
            v = cv2.remap(b, xs.astype(np.float32)[None], ys.astype(np.float32)[None], cv2.INTER_LINEAR)[0]
            k = int(np.argmax(v > thr))
            if v[k] > thr:
                pts.append((xs[k], ys[k]))
        P = np.array(pts, np.float64)
        for _ in range(2):
            A = np.c_[2 * P, np.ones(len(P))]
            sol, *_ = np.linalg.lstsq(A, (P**2).sum(1), rcond=None)
            c = sol[:2]
            r = float(np.sqrt(sol[2] + c @ c))
            res = np.abs(np.linalg.norm(P - c, axis=1) - r)
            P = P[res <= np.quantile(res, 0.8)]
        cx, cy = float(c[0]), float(c[1])
    return cx, cy, r, {"disc": inside, "median": outside, "threshold": thr}


def main() -> None:
    d = shared_data_dir() / "pivlab_karman"
    frames = [cv2.imread(str(d / f"PIVlab_Karman_0{i}.bmp"), cv2.IMREAD_GRAYSCALE) for i in range(1, 5)]
    if any(f is None for f in frames):
        raise SystemExit(f"{d}: PIVlab_Karman_0[1-4].bmp not found (set VIDSIM_SHARED_DATA)")
    cx, cy, r, lv = fit_dark_disc(np.mean(frames, 0))
    print(f"grey levels: disc {lv['disc']:.1f}, frame median {lv['median']:.1f}, edge threshold {lv['threshold']:.1f}")
    print(f"cylinder: centre ({cx:.1f}, {cy:.1f}) px, radius {r:.1f} px (1024x765 frame)")
    print(f"edit grid: centre ({(cx + 0.5) / PX_PER_NODE - 0.5:.2f}, {(cy + 0.5) / PX_PER_NODE - 0.5:.2f}) nodes, "
          f"radius {r / PX_PER_NODE:.2f} nodes")


if __name__ == "__main__":
    main()
