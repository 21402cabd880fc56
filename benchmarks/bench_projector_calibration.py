"""Accuracy of the cloth scene's projector calibration over calibration sessions (noise seeds).

For each seed, reality films the cloth studio's calibration session (the stage's own target,
camera at its still scale, the true projector) and ``calibrate_scene`` estimates camera and
projector from the images; the estimate is then compared with the true projector: focal lengths,
principal point, centre, and the reprojection of 200 points where the swatch hangs (a box
0.8 x 0.6 x 0.6 m around it).

    python benchmarks/bench_projector_calibration.py --seeds 10 --spread 0.5   # the default layout
    python benchmarks/bench_projector_calibration.py --seeds 10 --spread 0     # checker always centred
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hydra import compose, initialize_config_dir  # noqa: E402

from vidsim.cli.calibrate import board_to_world, target_for  # noqa: E402
from vidsim.config import CONF_DIR, camera_from_config, projector_from_config  # noqa: E402
from vidsim.video.calibration import ProjectorPattern, calibrate_scene, film_calibration_target, spread_patterns  # noqa: E402
from vidsim.video.camera import PinholeCamera  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--spread", type=float, default=None, help="calibrate.projector_pattern_spread (default: the config's)")
    ap.add_argument("--noise", type=float, default=None, help="sensor noise sd, grey levels (default: the config's)")
    a = ap.parse_args()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=["camera=cloth", "projector=cloth", "calibrate=cloth"])
    c = cfg.calibrate
    spread = float(c.projector_pattern_spread if a.spread is None else a.spread)
    noise = float(c.noise_sigma if a.noise is None else a.noise)
    cam = camera_from_config(cfg.camera).scaled(float(c.still_scale))
    proj = projector_from_config(cfg.projector)
    target = target_for(float(c.square_size), c.target_blank_width)
    T = board_to_world(np.asarray(c.target_origin, float))
    base = ProjectorPattern(width=proj.width, height=proj.height, square_px=int(c.projector_square_px))
    pat = spread_patterns(base, int(c.n_projector_views), spread) if spread > 0 else base
    X = np.random.default_rng(0).uniform([-0.4, -0.3, 0.7], [0.4, 0.3, 1.3], (200, 3))
    rows = []
    for seed in range(a.seeds):
        t = time.perf_counter()
        rng = np.random.default_rng(seed + 101)  # seed 0 is the stage's session at cfg.seed = 0
        ti, pi, names = film_calibration_target(cam, rng, target=target, projector=proj, pattern=pat, n_views=c.n_views,
                                                n_projector_views=c.n_projector_views, board_to_world=T, noise_sigma=noise)
        out = calibrate_scene(ti, pi, target=target, pattern=pat, reference_view=0, image_names=names, board_to_world=T)
        P = PinholeCamera.from_dict(out["projector"])
        rep = np.linalg.norm(P.project(X) - proj.project(X), axis=1)
        rows.append((P.K[0, 0], P.K[1, 1], 1000 * np.linalg.norm(P.center - proj.center), np.median(rep), rep.max()))
        print(f"seed {seed}: fx {P.K[0, 0]:.1f} fy {P.K[1, 1]:.1f} cx {P.K[0, 2]:.1f} cy {P.K[1, 2]:.1f} "
              f"(true {proj.K[0, 0]:.1f} {proj.K[1, 1]:.1f} {proj.K[0, 2]:.1f} {proj.K[1, 2]:.1f}); centre "
              f"{rows[-1][2]:.1f} mm off; projector RMS {out['projector_rms_px']:.3f} px over {out['projector_n_views']} "
              f"views; reprojection near the swatch median {rows[-1][3]:.2f} max {rows[-1][4]:.2f} px; "
              f"{time.perf_counter() - t:.1f} s", flush=True)
    r = np.array(rows)
    print(f"\nspread {spread}, noise {noise}, {a.seeds} sessions: fx {r[:, 0].min():.1f}-{r[:, 0].max():.1f}, centre "
          f"{r[:, 2].min():.1f}-{r[:, 2].max():.1f} mm off, reprojection median {r[:, 3].min():.2f}-{r[:, 3].max():.2f}, "
          f"max {r[:, 4].min():.2f}-{r[:, 4].max():.2f} px")


if __name__ == "__main__":
    main()
