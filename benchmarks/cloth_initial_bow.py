"""Would a buckled start help? The study's selections scored with the model's swatch started flat
(as the objective does) or bowed out of plane by +-a (a sin(pi s), s across the width, the same down
the height) before the usual settle and motion.

The estimator's swatch settles exactly planar, the MuJoCo reality buckled by 1-11 mm
(``benchmarks/cloth_settle_planarity.py``). If the planar start cost the fits, a bowed start should
match the footage's first frame better and lower the error of the trials. Prints, for each fabric's
own selection on its own three trials (exp1, exp2: fitted; robot: held out), the whole-clip error
and frame 0's fold and silhouette terms for each start, then which start the training trials
(E1 + E2) would choose and its held-out error against the flat start's. Experiment only: it replaces
the objective's (private) rig starts; the objective has no such option.

Usage (after the quick pipeline; the quick setting's model)::

    python benchmarks/cloth_initial_bow.py [--results results] [--amp 0.002 0.01]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import yaml  # noqa: E402
from hydra import compose, initialize_config_dir  # noqa: E402

import vidsim.config  # noqa: E402,F401  (registers the config schemas)
from vidsim.cli._app import CONF_DIR  # noqa: E402
from vidsim.cli.cloth_common import load_trial, make_objective, params_from_dict  # noqa: E402

QUICK = ["cloth.model.resolution=12", "cloth.model.frame_stride=2",
         "cloth.fit.estimate=[bend,stretch,shear,drag_linear,drag_quad]"]
FABRICS = ("linen", "fleece", "satin", "knit")
TRIALS = ("exp1", "exp2", "robot")


def set_bow(obj, a: float) -> None:
    """Start every swatch of ``obj`` bowed by ``a`` metres along its normal (0: flat, the default)."""
    for k, (mesh, drv, t0, col, _) in enumerate(obj._rigs):
        x = mesh.rest_positions
        c0, c1 = x[mesh.tags["top_corners"]]
        width = float(np.linalg.norm(c1 - c0))
        au = (c1 - c0) / width
        n = np.cross(au, x[-1] - x[0])
        n /= np.linalg.norm(n)
        s = np.clip((x - c0) @ au / width, 0.0, 1.0)
        x0 = None if a == 0 else x + a * np.sin(np.pi * s)[:, None] * n[None, :]
        obj._rigs[k] = (mesh, drv, t0, col, [x0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", default="results")
    ap.add_argument("--amp", type=float, nargs="+", default=[0.002, 0.01], help="bow amplitudes, metres")
    args = ap.parse_args()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=QUICK + [f"paths.results={args.results}"])
    for fab in FABRICS:
        sel = yaml.safe_load(open(f"{args.results}/cloth/select/{fab}/params.yaml"))["params"]
        p = params_from_dict(sel, fab)
        objs = {t: make_objective([load_trial(f"{args.results}/footage/cloth_{fab}_{t}", cfg)], cfg) for t in TRIALS}
        for amp in args.amp:
            score = {}
            for a in (0.0, amp, -amp):
                cells = []
                for t in TRIALS:
                    set_bow(objs[t], a)
                    r = objs[t].evaluate_params(p)
                    score[a, t] = r.score
                    cells.append(f"{t} {r.score:7.2f} (frame 0: fold {r.e_fold[0][0]:.3f}, silh {r.e_silh[0][0]:4.0f})")
                print(f"{fab:7s} start {a:+.3f} m: " + "; ".join(cells), flush=True)
            train = {a: score[a, "exp1"] + score[a, "exp2"] for a in (0.0, amp, -amp)}
            pick = min(train, key=train.get)
            print(f"{fab:7s} +-{amp} m: E1 + E2 chooses {pick:+.3f} m; held-out error {score[pick, 'robot']:.2f} "
                  f"(flat {score[0.0, 'robot']:.2f})", flush=True)


if __name__ == "__main__":
    main()
