"""Score the true and the selected parameters of a twin on its footage, with the model driven by
every measured corner sample (the objective since 4 Dec 2026) and by every k-th sample only (the
earlier strided drive), at the quick setting's model (12x12, every 2nd frame). Truth is read
from the twin's ``score.yaml`` for scoring only.

Usage (after the quick pipeline)::

    python benchmarks/twin_drive_check.py [--results results] [--twin twin|twinstiff]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import yaml  # noqa: E402
from hydra import compose, initialize_config_dir  # noqa: E402

import vidsim.config  # noqa: E402,F401  (registers the config schemas)
from vidsim.cli.cloth_common import load_trial, make_objective  # noqa: E402
from vidsim.clothfit.objective import Trial  # noqa: E402

QUICK = ["cloth.model.resolution=12", "cloth.model.frame_stride=2",
         "cloth.fit.estimate=[bend,stretch,shear,drag_linear,drag_quad]"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--results", default="results")
    ap.add_argument("--twin", default="twin")
    a = ap.parse_args()
    conf = Path(__file__).resolve().parents[1] / "conf"
    with initialize_config_dir(config_dir=str(conf), version_base=None):
        cfg = compose("config", overrides=QUICK)
    R = Path(a.results)
    sc = yaml.safe_load((R / "cloth" / "twin" / a.twin / "score.yaml").read_text())["parameters"]
    sets = {"truth": {k: v["truth"] for k, v in sc.items()}, "selected": {k: v["estimate"] for k, v in sc.items()}}
    print("trial | drive | " + " | ".join(sets))
    for trial in ("exp1", "exp2", "robot"):
        tr = load_trial(R / "footage" / f"cloth_{a.twin}_{trial}", cfg)
        strided = Trial(tr.name, tr.features, tr.times, tr.corner_paths, tr.camera, tr.projector, tr.size, tr.density)
        for label, t in (("full-rate", tr), ("strided", strided)):
            obj = make_objective([t], cfg)
            row = []
            for P in sets.values():
                obj.fixed = {k: v for k, v in P.items() if k not in obj.space.names}
                row.append(f"{obj.evaluate(np.array([P[n] for n in obj.space.names])).score:.2f}")
            print(f"{trial} | {label} | " + " | ".join(row), flush=True)


if __name__ == "__main__":
    main()
