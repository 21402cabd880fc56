"""Calibration (coverage) of the cloth posterior on twin realities with known truth, and its cost.

Usage::

    python benchmarks/bench_posterior_cloth.py [--cases 6] [--estimate bend stretch shear] \
        [--twin-resolution 12] [--resolution 12] [--stride 2] [--budget 40] [--grid-levels 3] \
        [--grid-params bend stretch shear] [--posterior-hydra posterior=quick] \
        [--work /tmp/vidsim_bench_posterior_cloth] [--json out.json]

Each case is a twin reality (the estimator's own simulator, ``cloth.reality.kind=twin``) whose
estimated parameters are drawn at random (seeded by the case number) in the middle half of their
configured ranges (the unit-cube coordinates 0.25-0.75; log-uniform on log axes), and whose sensor
noise has its own seed. The case runs the pipeline's own stages as subprocesses, as Snakemake would:
``cloth_reality`` (exp1, exp2), ``cloth_fit`` per trial (a ``--grid-levels`` grid over ``--grid-params`` +
``--budget`` annealing evaluations over all estimated parameters), ``cloth_select``, ``posterior_cloth``.
``--grid-params`` defaults to the estimated parameters when there are at most three (a full grid),
else to the pipeline's static grid ``bend stretch shear`` (a grid over nine would be 3^9 points). The parameters that
are not estimated are fixed at the twin's values (known, like the density): the reduced setting of
this benchmark. Only the scoring below reads the truth (``<footage>.truth.yaml``).

Reported per case and parameter: whether the central 90 % interval (summary.csv q05-q95) contains
the truth, the truth's quantile in the posterior samples (uniform on [0, 1] for a calibrated
posterior), and per case: converged flag, tau, the surrogate check's largest error, the stage's
wall and CPU time, ESS per minute, and the CPU time of every stage of the case (reality, fits,
selection, posterior; kept in ``<case>/timing.json`` so a continued run still reports them). Stage
outputs are reused when present (a stopped benchmark continues). Single thread per stage. ``--twin-resolution`` equal to ``--resolution`` removes the
mesh discrepancy (the twin then differs from the model only by sensor noise, blur and the twin's
longer settling); the twin's default 25 keeps it. A ``--posterior-hydra`` other than ``posterior=quick``
(``""``: the default posterior setting) samples the same realities and fits into ``posterior/cloth/twin__<overrides>``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from vidsim.cli.cloth_common import space_from_config  # noqa: E402
from vidsim.io.atomic import write_json  # noqa: E402
from vidsim.config.cloth import ClothRealityConfig, _default_space  # noqa: E402

FAST = ["log.rerun=false", "log.progress=false"]


def run(mod: str, *args: str) -> tuple[float, float]:
    """Run a stage; returns (wall s, child CPU s)."""
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
           "PYOPENGL_PLATFORM": "egl"}
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", mod, *args, *FAST], cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise RuntimeError(f"{mod} failed:\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}")
    return wall, (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)


def case_params(i: int, estimate: list[str]) -> dict[str, float]:
    """Twin parameters of case ``i``: the defaults, the estimated ones drawn in the middle half of the box."""
    base = dict(ClothRealityConfig().twin_params)
    space = space_from_config({n: _default_space()[n] for n in estimate})
    u = np.random.default_rng(1000 + i).uniform(0.25, 0.75, size=len(estimate))
    base.update(space.as_dict(space.from_unit(u)))
    return base


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", type=int, default=6)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--estimate", nargs="+", default=["bend", "stretch", "shear"])
    ap.add_argument("--resolution", type=int, default=12)
    ap.add_argument("--twin-resolution", type=int, default=12)
    ap.add_argument("--stride", type=int, default=2)
    ap.add_argument("--frames", type=int, default=50)
    ap.add_argument("--budget", type=int, default=40)
    ap.add_argument("--grid-levels", type=int, default=3)
    ap.add_argument("--grid-params", nargs="*", default=None,
                    help="static grid parameters (default: --estimate if at most 3, else bend stretch shear)")
    ap.add_argument("--posterior-hydra", default="posterior=quick")
    ap.add_argument("--work", default="/tmp/vidsim_bench_posterior_cloth")
    ap.add_argument("--json", default="")
    a = ap.parse_args()
    if a.grid_params is None:
        a.grid_params = list(a.estimate) if len(a.estimate) <= 3 else ["bend", "stretch", "shear"]
    bad = [p for p in a.grid_params if p not in a.estimate]
    if bad:
        ap.error(f"--grid-params {bad} are not in --estimate {a.estimate}")
    est = "all9" if sorted(a.estimate) == sorted(_default_space()) else "-".join(a.estimate)
    tag = f"est{est}_r{a.resolution}_tr{a.twin_resolution}_s{a.stride}_b{a.budget}"
    if a.grid_params != list(a.estimate) or a.grid_levels != 3:  # the first study's tag had neither
        tag += f"_g{'-'.join(a.grid_params)}x{a.grid_levels}"
    root = Path(a.work) / tag
    cal = Path(a.work) / "calibration" / "cloth" / "calibration.yaml"
    if not cal.is_file():
        run("vidsim.cli.calibrate", "camera=cloth", "projector=cloth", "calibrate=cloth", f"paths.results={a.work}",
            f"paths.out={cal.parent}")
    model = [f"cloth.model.resolution={a.resolution}", f"cloth.model.frame_stride={a.stride}",
             f"cloth.fit.estimate=[{','.join(a.estimate)}]", f"cloth.fit.grid_params=[{','.join(a.grid_params)}]",
             f"cloth.fit.budget={a.budget}", f"cloth.fit.grid_levels={a.grid_levels}", "cloth.fit.n_candidates=2"]
    # posteriors of other settings than the default ``posterior=quick`` go to their own folder
    # (``twin__<overrides>``) beside it, on the same realities and fits
    ptag = "" if a.posterior_hydra == "posterior=quick" else "__" + (re.sub(r"[^A-Za-z0-9.-]+", "_", a.posterior_hydra) or "default")
    rows = []
    for i in range(a.first, a.first + a.cases):
        R = root / f"case{i}"
        truth = case_params(i, a.estimate)
        fixed = [f"+cloth.fit.fixed.{k}={v!r}" for k, v in truth.items() if k not in a.estimate and k != "density"]
        folders, fits = [], []
        t_case = time.perf_counter()
        R.mkdir(parents=True, exist_ok=True)
        tfile = R / "timing.json"
        timing = json.loads(tfile.read_text()) if tfile.is_file() else {}

        def timed(key: str, mod: str, *args: str) -> tuple[float, float]:
            w, c = run(mod, *args)
            timing[key] = {"wall_s": w, "cpu_s": c}
            write_json(tfile, timing)
            return w, c

        for trial in ("exp1", "exp2"):
            fp = R / "footage" / f"cloth_twin_{trial}"
            if not (fp / "meta.yaml").is_file():
                timed(f"reality_{trial}", "vidsim.cli.cloth_reality", f"paths.results={R}", f"paths.calibration={cal}", f"paths.out={fp}",
                    "cloth.reality.kind=twin", f"cloth.reality.motion={trial}", f"cloth.reality.seed={i}",
                    f"cloth.reality.n_frames={a.frames}", f"cloth.reality.twin_resolution={a.twin_resolution}",
                    *[f"cloth.reality.twin_params.{k}={v!r}" for k, v in truth.items()])
            out = R / "cloth" / "fit" / f"twin_{trial}"
            if not (out / "fit.yaml").is_file():
                timed(f"fit_{trial}", "vidsim.cli.cloth_fit", f"paths.results={R}", f"paths.footage={fp}", f"paths.out={out}", *model,
                    *fixed)
            folders.append(str(fp))
            fits.append(str(out / "fit.yaml"))
        sel = R / "cloth" / "select" / "twin"
        if not (sel / "params.yaml").is_file():
            timed("select", "vidsim.cli.cloth_select", f"paths.results={R}", f"paths.out={sel}",
                f"cloth.select.fits=[{','.join(fits)}]", f"cloth.select.footage=[{','.join(folders)}]", *model, *fixed)
        post = R / "posterior" / "cloth" / ("twin" + ptag)
        wall = timing.get("posterior" + ptag, {}).get("wall_s", float("nan"))
        cpu = timing.get("posterior" + ptag, {}).get("cpu_s", float("nan"))
        if not (post / "posterior.yaml").is_file():
            wall, cpu = timed("posterior" + ptag, "vidsim.cli.posterior_cloth", f"paths.results={R}", f"paths.out={post}",
                            f"posterior.cloth.params={sel / 'params.yaml'}", f"posterior.cloth.fits=[{','.join(fits)}]",
                            f"posterior.cloth.footage=[{','.join(folders)}]", *model, *fixed,
                            *a.posterior_hydra.split())
        stage_cpu = {k: sum(v["cpu_s"] for n, v in timing.items() if n.startswith(k) and not n.startswith("posterior"))
                     for k in ("reality", "fit", "select")}
        stage_cpu["posterior"] = timing.get("posterior" + ptag, {}).get("cpu_s", 0.0)
        # ---- scoring: the only place that reads the truth
        tdoc = yaml.safe_load(Path(f"{folders[0]}.truth.yaml").read_text())
        pdoc = yaml.safe_load((post / "posterior.yaml").read_text())
        summ = {r.split(",")[0]: r.split(",") for r in (post / "summary.csv").read_text().splitlines()[1:]}
        ch = np.load(post / "chain.npz")
        burn = int(pdoc["diagnostics"]["burn"])
        S = ch["chain"][burn:].reshape(-1, ch["chain"].shape[2])
        space = space_from_config({n: _default_space()[n] for n in pdoc["names"]})
        tu = space.to_unit(np.array([tdoc["params"][n] for n in pdoc["names"]]))
        for j, n in enumerate(pdoc["names"]):
            q05, med, q95 = float(summ[n][3]), float(summ[n][4]), float(summ[n][5])
            t = float(tdoc["params"][n])
            rows.append({"case": i, "param": n, "truth": t, "point": float(summ[n][2]), "q05": q05, "median": med,
                         "q95": q95, "covered": bool(q05 <= t <= q95), "quantile": float(np.mean(S[:, j] <= tu[j])),
                         "converged": pdoc["diagnostics"]["converged"], "tau_max": pdoc["diagnostics"]["tau_max"],
                         "steps": pdoc["diagnostics"]["n_steps"], "w": pdoc["diagnostics"]["w"],
                         "check_max_logp": pdoc["surrogate_check"]["max_abs_error_logp"],
                         "check_max_logp_offset_free": pdoc["surrogate_check"]["max_abs_error_logp_offset_free"],
                         "check_ok": pdoc["surrogate_check"]["ok"],
                         "check_max_loss": pdoc["surrogate_check"]["max_abs_error"],
                         "ess_per_min_sampling": pdoc["diagnostics"]["ess_per_min_sampling"],
                         "ess_per_min_stage": pdoc["diagnostics"]["ess_per_min_stage"],
                         "stage_s": pdoc["diagnostics"]["seconds"]["stage"], "wall_s": wall, "cpu_s": cpu,
                         "true_evals": pdoc["diagnostics"]["true_evaluations"],
                         **{f"cpu_{k}_s": v for k, v in stage_cpu.items()},
                         "multimodal": pdoc["diagnostics"]["multimodal"]})
            r = rows[-1]
            print(f"case {i} {n:>15}: truth {t:.4g} point {r['point']:.4g} 90% [{q05:.4g}, {q95:.4g}] "
                  f"covered {r['covered']} quantile {r['quantile']:.2f}", flush=True)
        r = rows[-1]
        print(f"case {i}: converged {r['converged']} ({r['steps']} steps, tau_max {r['tau_max']:.1f}), w {r['w']:.4g}, "
              f"surrogate max error {r['check_max_logp']:.3g} log-density ({r['check_max_loss']:.3g} loss), ok "
              f"{r['check_ok']}, posterior stage {r['stage_s']:.0f} s (cpu {cpu:.0f} s), ESS/min {r['ess_per_min_stage']:.0f}, "
              f"case {time.perf_counter() - t_case:.0f} s, load {os.getloadavg()[0]:.1f}", flush=True)
        print(f"case {i}: CPU s per stage " + ", ".join(f"{k} {v:.0f}" for k, v in stage_cpu.items())
              + " (a stage reused from an earlier run without timing.json counts 0)", flush=True)
    cov = np.array([r["covered"] for r in rows])
    print(f"\ncoverage of the 90 % intervals: {cov.mean():.3f} ({cov.sum()}/{cov.size} (case, parameter) pairs) over "
          f"{a.cases} cases [{tag}, posterior overrides {a.posterior_hydra!r}]")
    for n in a.estimate:
        c = [r["covered"] for r in rows if r["param"] == n]
        print(f"  {n}: {np.mean(c):.2f} ({sum(c)}/{len(c)})")
    per_case = {r["case"]: r for r in rows}
    print(f"surrogate check, largest error over cases: {max(r['check_max_logp'] for r in per_case.values()):.3g} "
          f"log-density units; converged {sum(r['converged'] for r in per_case.values())}/{len(per_case)}; "
          f"median posterior stage {np.median([r['stage_s'] for r in per_case.values()]):.0f} s; median ESS/min "
          f"{np.median([r['ess_per_min_stage'] for r in per_case.values()]):.0f} (stage), "
          f"{np.median([r['ess_per_min_sampling'] for r in per_case.values()]):.0f} (sampling)")
    for k in ("reality", "fit", "select", "posterior"):
        v = [r[f"cpu_{k}_s"] for r in per_case.values()]
        print(f"  CPU s per case, {k}: median {np.median(v):.0f}, range {min(v):.0f}-{max(v):.0f}")
    if a.json:
        write_json(a.json, {"tag": tag, "rows": rows, "coverage": float(cov.mean())})  # strict: non-finite as null


if __name__ == "__main__":
    main()
