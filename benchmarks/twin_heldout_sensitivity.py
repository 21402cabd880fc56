"""How far the held-out error moves when the *true* parameters of a twin move a little: the scale
against which issue 5's criterion "the recovered parameters reproduce the held-out motion with an
error within 10 % of the true parameters' error" can be read.

The twin's held-out footage (the robot motion) is scored by the estimator's own objective for the
true parameters and for the true parameters changed (a) one at a time by a factor (0.9, 0.95,
1.05, 1.1) and (b) every parameter the setting estimates (quick: five, full: all nine) at once by
independent log-normal factors exp(N(0, sigma)), as ``score_cloth_twin``'s truth scale does. Prints each ratio to the truth's error, and per sigma the quantiles of the ratio
and the fraction of draws within the criterion (ratio <= 1.10). A diagnostic, not an estimator:
it reads the truth file beside the footage, like ``score_cloth_twin``.

Usage (after the pipeline; ``--setting quick`` applies the quick profile's model overrides from
``workflow/config/quick.yaml``, ``full`` the defaults)::

    python benchmarks/twin_heldout_sensitivity.py --results results --twin twinstiff --setting quick
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shlex
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import yaml  # noqa: E402
from hydra import compose, initialize_config_dir  # noqa: E402

import vidsim.config  # noqa: E402,F401  (registers the config schemas)
from vidsim.cli.cloth_common import load_trial, make_objective, params_from_dict  # noqa: E402
from vidsim.io.footage import read_truth  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ONE_AT_A_TIME = ("bend", "stretch", "shear", "drag_linear", "drag_quad", "drag_degrade", "stretch_damping")


def quick_overrides() -> list[str]:
    """The quick profile's cloth overrides that change the model or the estimated parameters (not the
    fit's budget)."""
    hydra = yaml.safe_load((ROOT / "workflow" / "config" / "quick.yaml").read_text())["cloth"]["hydra"]
    return [o for o in shlex.split(hydra) if o.startswith(("cloth.model.", "cloth.fit.estimate="))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--results", default="results")
    ap.add_argument("--twin", default="twinstiff")
    ap.add_argument("--trial", default="robot", help="which of the twin's footage folders (default: the held-out one)")
    ap.add_argument("--setting", choices=("quick", "full"), default="quick")
    ap.add_argument("--sigmas", default="0.02,0.05", help="comma-separated log-normal scales of the joint draws")
    ap.add_argument("--draws", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    overrides = [f"paths.results={a.results}"] + (quick_overrides() if a.setting == "quick" else [])
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose("config", overrides=overrides)
    folder = Path(a.results) / "footage" / f"cloth_{a.twin}_{a.trial}"
    truth = params_from_dict(read_truth(folder)["params"], f"truth of {folder}")
    obj = make_objective([load_trial(folder, cfg)], cfg)

    def ratio(p) -> float:
        return float(obj.evaluate_params(p).score) / e_true

    e_true = 1.0
    e_true = float(obj.evaluate_params(truth).score)
    print(f"{folder} ({a.setting}: {' '.join(overrides[1:]) or 'defaults'}): true parameters' error {e_true:.2f}")
    factors = (0.9, 0.95, 1.05, 1.1)
    print("parameter | " + " | ".join(f"x{f:g}" for f in factors))
    for n in ONE_AT_A_TIME:
        r = [ratio(dataclasses.replace(truth, **{n: getattr(truth, n) * f})) for f in factors]
        print(f"{n} | " + " | ".join(f"{x:.3f}" for x in r), flush=True)
    rng = np.random.default_rng(a.seed)
    for s in (float(x) for x in a.sigmas.split(",")):
        r = np.array([ratio(dataclasses.replace(truth, **{n: getattr(truth, n) * float(np.exp(rng.normal(0, s)))
                                                         for n in obj.space.names})) for _ in range(a.draws)])
        q = np.quantile(r, [0.1, 0.5, 0.9])
        print(f"the {len(obj.space.names)} estimated x exp(N(0, {s:g})), {a.draws} draws: ratio 10/50/90 % {q[0]:.3f} / {q[1]:.3f} / {q[2]:.3f}, "
              f"max {r.max():.3f}; within 1.10: {np.mean(r <= 1.10):.0%}", flush=True)


if __name__ == "__main__":
    main()
