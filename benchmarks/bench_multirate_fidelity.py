"""Fidelity of the cloth model's multirate scheme: the error of the TRUE parameters on twin footage.

A twin (the estimator's own simulator at 24x24, plain velocity Verlet) is filmed with the study's
camera and projector; the 16x16 model then scores the true parameters, and the truth with one
parameter scaled (stretch x10 and x0.1, bend x30, shear x0.1), at multirate factors r. A scheme
that moves the model away from the twin raises the truth's error and can let wrong parameters win.

    python benchmarks/bench_multirate_fidelity.py --motion exp1 --r 1 2 4 8
    python benchmarks/bench_multirate_fidelity.py --motion exp1 --params 1e-4 2000 300   # a stiff twin
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from omegaconf import OmegaConf  # noqa: E402

from vidsim.cloth import ClothParams  # noqa: E402
from vidsim.clothfit.features import FeatureSettings, extract_features  # noqa: E402
from vidsim.clothfit.film import FilmSettings, film_cloth, twin_swatch  # noqa: E402
from vidsim.clothfit.objective import ClothObjective, ModelSettings, Trial, space_from_config  # noqa: E402
from vidsim.config import camera_from_config, projector_from_config  # noqa: E402
from vidsim.config.cloth import ClothConfig  # noqa: E402
from vidsim.reality.cloth import corner_paths, swatch_motion  # noqa: E402
from vidsim.render.projector import Projector  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--motion", default="exp1")
    ap.add_argument("--params", nargs=3, type=float, default=[3e-6, 300.0, 40.0], metavar=("BEND", "STRETCH", "SHEAR"))
    ap.add_argument("--r", nargs="+", default=["1", "2", "4"])
    a = ap.parse_args()
    true = ClothParams(bend=a.params[0], stretch=a.params[1], shear=a.params[2], bend_damping=3e-8, stretch_damping=3e-3,
                       shear_damping=3e-3, drag_linear=0.4, drag_quad=0.8, drag_degrade=0.2, density=0.2)
    cfg = OmegaConf.structured(ClothConfig())
    cam = camera_from_config(cfg.camera)
    proj = Projector(projector_from_config(cfg.projector), period_px=cfg.projector.period_px, power=cfg.projector.power,
                     ambient=cfg.projector.ambient)
    mot = swatch_motion(a.motion)
    V, F, cp, ok, failure = twin_swatch(true, lambda t: corner_paths(mot, t), n_frames=24, fps=30.0, resolution=24,
                                        settle_s=0.5)
    if not ok:
        raise SystemExit(f"the twin failed: {failure}")
    frames = film_cloth(V, F, cam, proj, np.random.default_rng(3), FilmSettings(n_background=4))
    fs = FeatureSettings()
    tr = Trial(f"twin/{a.motion}", extract_features(frames, np.arange(4), fs), np.arange(24) / 30.0, cp, cam, proj, 0.3, 0.2)
    space = space_from_config(dict(cfg.fit.space))
    print(f"twin {a.motion}, bend {a.params[0]:g} N m, stretch {a.params[1]:g} N/m, shear {a.params[2]:g} N/m")
    for r in a.r:
        obj = ClothObjective([tr], space, model=ModelSettings(resolution=16, settle_s=0.5, multirate=r), features=fs)
        th = obj.theta_of(true)
        e = obj.evaluate(th).score
        out = []
        for name, fac in (("stretch", 10.0), ("stretch", 0.1), ("bend", 30.0), ("shear", 0.1)):
            t2 = th.copy()
            t2[space.names.index(name)] *= fac
            out.append(f"{name} x{fac:g}: {obj.evaluate(t2).score / e:.3f}")
        print(f"r {r}: error of the truth {e:.2f}; relative to it " + ", ".join(out), flush=True)


if __name__ == "__main__":
    main()
