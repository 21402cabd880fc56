"""Studio design study: can the footage tell the four MuJoCo fabrics apart, and can the model follow them?

Two measurements behind the cloth studio's defaults (air on, camera 40 degrees off the swatch's
normal, motions without grip squeeze; docs/cloth_study.md, "Studio design"):

* ``separation`` (default): every fabric is simulated by the MuJoCo reality along one motion and
  filmed noise-free by the fast stripe renderer with the configured camera and projector (or the
  whole rig turned to ``--azimuth`` degrees about the vertical through the swatch); each fabric's
  footage is scored against every other's with the estimator's metric (fold + 0.1 x silhouette,
  seed eqs. 12-16, mean per frame, rendered silhouettes). The off-diagonal says how far apart the
  fabrics are *for the metric*; the diagonal is 0 by construction.
* ``oracle``: how closely the estimator's Baraff-Witkin model, at the reality's mesh resolution
  (vertex for vertex), can follow one MuJoCo fabric in 3D: CMA-ES over the nine parameters
  (the fit space's unit cube) minimising the RMS vertex distance over the clip. **This reads the
  reality's vertices (truth)**: it is a study of the reality/model pair, never part of an estimate.

Usage::

    python benchmarks/cloth_studio_design.py separation [--motion exp1] [--azimuth 40] [--no-air] [--squeeze 0.35]
    python benchmarks/cloth_studio_design.py oracle --fabric linen [--motion exp1] [--no-air] [--budget 300]

Single core; one MuJoCo run costs 2-3 s, one model run at 15x15 about 0.5 s.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import cv2
import numpy as np
from omegaconf import OmegaConf

from vidsim.cloth import mid_range_params, simulate
from vidsim.clothfit.film import swatch_driver, swatch_model_mesh
from vidsim.clothfit.objective import space_from_config
from vidsim.config import camera_from_config, projector_from_config
from vidsim.config.cloth import ClothConfig, _default_space
from vidsim.reality.cloth import fabric_profile, simulate_swatch, swatch_motion
from vidsim.render.projector import Projector, render_stripes_batch
from vidsim.video.anglemap import angle_map, cloth_metric
from vidsim.video.camera import look_at

NAMES = ["linen", "fleece", "satin", "knit"]


def _turn(eye: list[float], target: list[float], deg: float) -> np.ndarray:
    """``eye`` turned by ``deg`` degrees about the vertical axis through ``target``."""
    a = np.deg2rad(deg)
    e, c = np.asarray(eye, float), np.asarray(target, float)
    d = e - c
    return c + np.array([np.cos(a) * d[0] - np.sin(a) * d[1], np.sin(a) * d[0] + np.cos(a) * d[1], d[2]])


def rig(azimuth: float | None):
    """(camera, projector) of the cloth config, optionally the rig turned to ``azimuth`` (degrees from the normal)."""
    cfg = OmegaConf.structured(ClothConfig())
    if azimuth is not None:
        # the configured rig's azimuth (camera eye about the swatch normal -y)
        e = np.asarray(cfg.camera.eye, float) - np.asarray(cfg.camera.target, float)
        now = np.degrees(np.arctan2(e[0], -e[1]))
        for dev in (cfg.camera, cfg.projector):
            dev.eye = _turn(list(dev.eye), list(dev.target), azimuth - now).tolist()
    cam = camera_from_config(cfg.camera)
    proj = Projector(projector_from_config(cfg.projector), period_px=cfg.projector.period_px,
                     power=cfg.projector.power, ambient=cfg.projector.ambient)
    return cam, proj


def motion(name: str, squeeze: float) -> dict:
    m = swatch_motion(name)
    if squeeze:
        m["squeeze"] = squeeze
    return m


def separation(a: argparse.Namespace) -> None:
    cv2.setNumThreads(1)
    cam, proj = rig(a.azimuth)
    eff = {"air_drag": {"on": not a.no_air}}
    feat = {}
    for fab in NAMES:
        t0 = time.perf_counter()
        run = simulate_swatch(fabric_profile(fab), motion(a.motion, a.squeeze), eff, np.random.default_rng(0))
        imgs, depth = render_stripes_batch(run.vertices, run.faces, cam, proj)
        sil = np.isfinite(depth)
        ams = [angle_map(imgs[i], region=sil[i]) for i in range(len(imgs))]
        feat[fab] = (np.array([m.theta for m in ams]), np.array([m.mask(a.tau) for m in ams]), sil)
        print(f"{fab:7s} {time.perf_counter() - t0:5.1f} s: silhouette {sil.sum((1, 2)).mean():.0f} px/frame, "
              f"fold mask {feat[fab][1].sum((1, 2)).mean():.0f} px/frame", flush=True)
    print(f"motion {a.motion} (squeeze {a.squeeze}), air {'off' if a.no_air else 'on'}, rig azimuth "
          f"{'as configured' if a.azimuth is None else a.azimuth}: E per frame (fold part), rows = footage, columns = other fabric")
    print("         " + " ".join(f"{n:>14s}" for n in NAMES))
    off = []
    for x in NAMES:
        row = [cloth_metric(*feat[x], feat[y][0], feat[y][2]) for y in NAMES]
        off += [r[0] for y, r in zip(NAMES, row) if y != x]
        print(f"{x:8s} " + " ".join(f"{r[0]:7.1f} ({np.mean(r[1]):4.1f})" for r in row))
    print(f"smallest off-diagonal {min(off):.1f}, median {np.median(off):.1f}")


def oracle(a: argparse.Namespace) -> None:
    import cma

    f = fabric_profile(a.fabric)
    eff = {"air_drag": {"on": not a.no_air}}
    run = simulate_swatch(f, motion(a.motion, a.squeeze), eff, np.random.default_rng(0), resolution=a.resolution)
    V, times, cp = run.vertices, run.times, run.corner_paths_measured
    rest = np.asarray(run.truth["rest_vertices"])
    mesh = swatch_model_mesh(cp[0], a.resolution, 0.3)
    idx = np.argmin(np.linalg.norm(mesh.rest_positions[:, None] - rest[None], axis=2), axis=1)
    drv, t0 = swatch_driver(mesh, times, cp, float(run.truth["settle_s"]))
    space = space_from_config(_default_space())
    base = mid_range_params(density=f["areal_density"])

    def rms_mm(p) -> float:
        r = simulate(mesh, p, drv, times, integrator="fast", t0=t0)
        return float(np.sqrt(np.mean(np.sum((r.positions - V[:, idx]) ** 2, axis=2))) * 1e3) if r.ok else 1e3

    analogue = base.replace(bend=f["bend"], stretch=f["stretch"], shear=f["stretch"] / (2 * (1 + f["poisson"])),
                            drag_quad=0.0 if a.no_air else 0.6 * f["drag"], drag_linear=0.0, drag_degrade=0.0)
    print(f"{a.fabric}/{a.motion} (squeeze {a.squeeze}), air {'off' if a.no_air else 'on'}, {a.resolution}x{a.resolution}: "
          f"RMS vertex distance of the analogue parameters {rms_mm(analogue):.1f} mm, of mid-range {rms_mm(base):.1f} mm",
          flush=True)
    t = time.perf_counter()
    es = cma.CMAEvolutionStrategy(np.full(space.dim, 0.5), 0.25,
                                  {"bounds": [0, 1], "maxfevals": a.budget, "seed": 1, "verbose": -9})
    best = (np.inf, None)
    while not es.stop():
        X = es.ask()
        Y = [rms_mm(base.replace(**space.as_dict(space.from_unit(np.clip(x, 0, 1))))) for x in X]
        es.tell(X, Y)
        i = int(np.argmin(Y))
        if Y[i] < best[0]:
            best = (Y[i], np.clip(X[i], 0, 1))
    p = space.as_dict(space.from_unit(best[1]))
    print(f"oracle RMS {best[0]:.1f} mm after {es.countevals} evaluations ({time.perf_counter() - t:.0f} s): "
          + " ".join(f"{k}={v:.3g}" for k, v in p.items()))
    print("fabric (MuJoCo): " + " ".join(f"{k}={v:.3g}" for k, v in f.items()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mode", nargs="?", default="separation", choices=["separation", "oracle"])
    ap.add_argument("--motion", default="exp1")
    ap.add_argument("--squeeze", type=float, default=0.0, help="grip squeeze fraction added to the motion")
    ap.add_argument("--no-air", action="store_true", help="film in vacuum (the air model off)")
    ap.add_argument("--azimuth", type=float, default=None, help="turn the camera+projector rig to this azimuth (deg)")
    ap.add_argument("--tau", type=float, default=0.04, help="gradient-mask threshold, rad/px")
    ap.add_argument("--fabric", default="linen")
    ap.add_argument("--budget", type=int, default=300)
    ap.add_argument("--resolution", type=int, default=15)
    a = ap.parse_args()
    separation(a) if a.mode == "separation" else oracle(a)


if __name__ == "__main__":
    main()
