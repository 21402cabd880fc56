"""Why satin's fits choose linen-like (stiff) parameters: chaos, measured (docs/cloth_study.md, "Session 43").

A study of the reality/model pair that **reads truth** (MuJoCo's vertices and fabric profiles); it is
never part of an estimate. Three measurements, each on the exp1, exp2 and robot motions of the MuJoCo
swatch in air (resolution 15, the reality's default mesh):

* ``reality``: how chaotic each MuJoCo fabric is: the fabric's stretch, bend and damping moved by
  1e-4 (relative, two seeded draws), RMS and largest vertex change against the unmoved run.
* ``sets``: parameter sets of the estimator's Baraff-Witkin model (``--sets`` JSON file,
  ``{"name": {"bend": ..., ...}}``, the rest mid-range; default: the 3D oracles printed by
  ``benchmarks/cloth_studio_design.py oracle --fabric satin|linen``, below), each with ``--copies``
  copies moved by 1e-4, scored by (a) the RMS 3D vertex distance to the reality (model at the
  reality's mesh, vertex for vertex) and (b) the study's image objective (seed eqs. 12-16) on footage
  of the reality filmed with the configured camera and projector, model at ``--resolution``.
  The median over the copies is what an estimator can expect from the set; the first copy alone is
  what one run shows.

    python benchmarks/cloth_chaos_study.py reality
    python benchmarks/cloth_chaos_study.py sets --fabric satin [--copies 5] [--resolution 15]

Single core; ``reality`` about 40 s, ``sets`` about 2 min per fabric.
"""

from __future__ import annotations

import argparse
import json
import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import cv2
import numpy as np
from omegaconf import OmegaConf

from vidsim.cloth import mid_range_params, simulate
from vidsim.clothfit.features import FeatureSettings, extract_features
from vidsim.clothfit.film import FilmSettings, film_cloth, swatch_driver, swatch_model_mesh
from vidsim.clothfit.objective import ClothObjective, ModelSettings, Trial, space_from_config
from vidsim.config import camera_from_config, projector_from_config
from vidsim.config.cloth import ClothConfig
from vidsim.reality.cloth import fabric_profile, simulate_swatch, swatch_motion
from vidsim.render.projector import Projector

MOTIONS = ["exp1", "exp2", "robot"]
#: the nine parameters of the 3D oracles (CMA-ES on MuJoCo's vertices, 310 evaluations, exp1, 15x15;
#: `cloth_studio_design.py oracle`, 6 Dec 2026), and satin's oracle with linen-like bending
DEFAULT_SETS = {
    "satin_oracle": {"bend": 4.96e-07, "stretch": 4000, "shear": 338, "bend_damping": 1.83e-08,
                     "stretch_damping": 0.000263, "shear_damping": 0.000969, "drag_linear": 0.0267,
                     "drag_quad": 1.55, "drag_degrade": 0.942},
    "satin_oracle_bend1e-4": {"bend": 1.0e-04, "stretch": 4000, "shear": 338, "bend_damping": 1.83e-08,
                              "stretch_damping": 0.000263, "shear_damping": 0.000969, "drag_linear": 0.0267,
                              "drag_quad": 1.55, "drag_degrade": 0.942},
    "linen_oracle": {"bend": 3.67e-05, "stretch": 3690, "shear": 369, "bend_damping": 6.67e-07,
                     "stretch_damping": 0.0702, "shear_damping": 0.0057, "drag_linear": 0.0167,
                     "drag_quad": 1.62, "drag_degrade": 0.89},
}
AIR = {"air_drag": {"on": True}}


def moved(d: dict, keys, seed: int) -> dict:
    """``d`` with ``keys`` scaled by 1 + 1e-4 N(0, 1) (seeded)."""
    rng = np.random.default_rng(seed)
    return {**d, **{k: d[k] * (1 + 1e-4 * rng.standard_normal()) for k in keys}}


def reality(_: argparse.Namespace) -> None:
    for fab in ["linen", "fleece", "satin", "knit"]:
        f = fabric_profile(fab)
        for m in MOTIONS[:2]:
            base = simulate_swatch(f, swatch_motion(m), AIR, np.random.default_rng(0)).vertices
            d = [np.sqrt(np.sum((simulate_swatch(moved(f, ("stretch", "bend", "damping"), s), swatch_motion(m), AIR,
                                                 np.random.default_rng(0)).vertices - base) ** 2, axis=2)) * 1e3
                 for s in (1, 2)]
            print(f"MuJoCo {fab:6s} {m}: moved by 1e-4, RMS vertex change "
                  f"{' / '.join(f'{np.sqrt(np.mean(x ** 2)):.2f}' for x in d)} mm "
                  f"(largest {' / '.join(f'{x.max():.1f}' for x in d)} mm)", flush=True)


def sets(a: argparse.Namespace) -> None:
    cv2.setNumThreads(1)
    table = DEFAULT_SETS
    if a.sets:
        try:
            table = json.loads(open(a.sets).read())
        except (OSError, json.JSONDecodeError) as e:
            raise SystemExit(f"cloth_chaos_study: --sets {a.sets}: {e} (expected a JSON object of parameter sets)")
    f = fabric_profile(a.fabric)
    cfg = OmegaConf.structured(ClothConfig())
    cam = camera_from_config(cfg.camera)
    proj = Projector(projector_from_config(cfg.projector), period_px=cfg.projector.period_px,
                     power=cfg.projector.power, ambient=cfg.projector.ambient)
    fs = FeatureSettings()
    for m in MOTIONS:
        run = simulate_swatch(f, swatch_motion(m), AIR, np.random.default_rng(0))
        V, times, cp = run.vertices, run.times, run.corner_paths_measured
        rest = np.asarray(run.truth["rest_vertices"])
        n_side = int(round(np.sqrt(rest.shape[0])))
        mesh = swatch_model_mesh(cp[0], n_side, 0.3)
        idx = np.argmin(np.linalg.norm(mesh.rest_positions[:, None] - rest[None], axis=2), axis=1)
        drv, t0 = swatch_driver(mesh, times, cp, float(run.truth["settle_s"]))
        frames = film_cloth(V, run.faces, cam, proj, np.random.default_rng(1), FilmSettings())
        feat = extract_features(frames, np.arange(FilmSettings().n_background), fs)
        tr = Trial(f"{a.fabric}/{m}", feat, times, cp, cam, proj, 0.3, f["areal_density"])
        obj = ClothObjective([tr], space_from_config(dict(cfg.fit.space)), model=ModelSettings(resolution=a.resolution),
                             features=fs)
        for name, kw in table.items():
            rms, img = [], []
            for k in range(a.copies):
                p = mid_range_params(density=f["areal_density"]).replace(**(kw if k == 0 else moved(kw, kw, 1000 + k)))
                r = simulate(mesh, p, drv, times, integrator="fast", t0=t0)
                rms.append(float(np.sqrt(np.mean(np.sum((r.positions - V[:, idx]) ** 2, axis=2))) * 1e3) if r.ok
                           else float("nan"))
                img.append(obj.evaluate_params(p).score)
            print(f"{a.fabric} footage, {m:5s} {name:22s} 3D RMS median {np.median(rms):5.1f} mm "
                  f"({min(rms):.1f}-{max(rms):.1f}; unmoved {rms[0]:.1f}) | image E median {np.median(img):6.1f} "
                  f"({min(img):.1f}-{max(img):.1f}; unmoved {img[0]:.1f})", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mode", choices=["reality", "sets"])
    ap.add_argument("--fabric", default="satin")
    ap.add_argument("--sets", default=None, help="JSON file of parameter sets (default: the 3D oracles)")
    ap.add_argument("--copies", type=int, default=5)
    ap.add_argument("--resolution", type=int, default=15, help="the model's vertices per side for the image objective")
    a = ap.parse_args()
    if a.copies < 1:
        ap.error(f"--copies must be >= 1, got {a.copies}")
    {"reality": reality, "sets": sets}[a.mode](a)


if __name__ == "__main__":
    main()
