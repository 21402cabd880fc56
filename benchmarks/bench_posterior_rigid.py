"""Calibration (coverage) of the rigid posterior on synthetic throws with known truth, and its cost.

Usage::

    python benchmarks/bench_posterior_rigid.py [--seeds 1000 ... 1019] [--drag 0] \
        [--noise sandwich sandwich_hac iid_pixel] [--max-steps 3000] [--json out.json] [--laplace] \
        [--discrepancy quadratic_drag]

Each throw is filmed (pyrender + sensor noise + JPEG) and segmented once, cached in
``/tmp/vidsim_posterior_throws`` (not timed), fitted from a guess 10 degrees / 20 % off the truth
(``multistart: none``, timed separately), then sampled for every noise model. Reported: the
fraction of (throw, parameter) pairs whose central 90 % interval contains the truth, convergence
(chain >= 50 autocorrelation times), the posterior's time per throw and the effective sample size
per minute. ``--drag k`` films reality with k x physical air drag (linear and angular) that the
model does not have (withheld effect). ``--laplace`` skips the sampler and scores the Gaussian
approximation N(mode, (w H)^-1) of the noise calibration instead (cheap). ``--discrepancy e ...``
samples those gap-library effects as nuisance parameters (structured discrepancy,
:class:`vidsim.posterior.rigid.DiscrepancyConfig`) for every noise model; the 14 parameters are then
scored on their marginal (Laplace: the Gaussian truncated to the nuisance prior, by rejection).
``--noise sandwich_holdout:4``: the held-out inflation from 4 consecutive blocks (``NoiseConfig.holdout_blocks``);
``sandwich_holdout@0.9``: its upper 90 % confidence bound (``NoiseConfig.holdout_confidence``).
Single thread.
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _posterior_throws import throw_data  # noqa: E402

from vidsim.io.atomic import write_json  # noqa: E402
from vidsim.posterior.rigid import (ANGLE_IDX, DiscrepancyConfig, FrameLoss, NoiseConfig,  # noqa: E402
                                   calibrate_noise, laplace_samples, refit_discrepancy, rigid_posterior,
                                   to_natural, truth_params)
from vidsim.posterior.sampler import SamplerConfig, covered  # noqa: E402
from vidsim.rigid.body import BoxBody  # noqa: E402
from vidsim.rigid.dynamics import PARAM_NAMES  # noqa: E402
from vidsim.rigid.evaluate import perturbed_guess  # noqa: E402
from vidsim.rigid.fit import fit_throw  # noqa: E402
from vidsim.video.camera import PinholeCamera  # noqa: E402


def noise_config(model: str) -> NoiseConfig:
    """``sandwich_holdout:4`` -> the holdout noise model comparing 4 consecutive blocks;
    ``sandwich_holdout@0.9`` -> the halves' inflation at its upper 90 % confidence bound."""
    model, _, c = model.partition("@")
    name, _, k = model.partition(":")
    return NoiseConfig(model=name, holdout_blocks=int(k) if k else 2, holdout_confidence=float(c) if c else 0.0)


def label(model: str, effects: tuple[str, ...], signed: bool = False) -> str:
    """Row name of a noise model with the nuisance effects (``sandwich+quadratic_drag``, ``+signed``)."""
    return "+".join((model,) + tuple(effects) + (("signed",) if signed and effects else ()))


def laplace_rows(seed: int, drag: float, models: list[str], d: dict, cam, body, fit, truth: dict,
                 effects: tuple[str, ...] = (), signed: bool = False, refit_nfev: int = 15) -> list[dict]:
    """Coverage of the Gaussian (Laplace) approximation ``N(center, (w H)^-1)`` of each noise model.

    With ``effects`` the mode is refitted with the nuisance free (once per throw, timed with the first
    model) and the Gaussian is truncated to the nuisance prior; the 14 parameters are scored on the
    central 90 % interval of its draws' marginals.
    """
    rows = []
    disc = DiscrepancyConfig(effects=tuple(effects), signed=signed, refit_nfev=refit_nfev)
    disc.validate()
    t_refit = time.perf_counter()
    loss = FrameLoss(body, cam, fit.times, d["masks"][fit.frames], fit.t0, fit.q0, effects=disc.effects)
    p0 = refit_discrepancy(d["masks"][fit.frames], loss, fit.params, disc) if effects else fit.params
    t_refit = time.perf_counter() - t_refit
    tp = to_natural(truth_params(truth, fit.q0, body.symmetries))
    for i, m in enumerate(models):
        t = time.perf_counter()
        nm = calibrate_noise(loss, p0, noise_config(m), np.random.default_rng(0))
        if effects:
            S = to_natural(laplace_samples(nm, disc.bounds(), 20000, np.random.default_rng(1)))
            cov = covered(S[:, :14], tp, 90.0)
            z = (np.median(S[:, :14], 0) - tp) / S[:, :14].std(0)
            nuis = np.percentile(S[:, 14:], [5, 50, 95], axis=0).T.tolist()
        else:
            c = to_natural(nm.center)
            sd = np.sqrt(np.diag(nm.cov)) * np.where(np.isin(np.arange(14), ANGLE_IDX), 180 / np.pi, 1.0)
            z = (c - tp) / sd
            cov = np.abs(z) <= 1.6449
            nuis = []
        secs = time.perf_counter() - t + (t_refit if i == 0 else 0.0)
        rows.append({"seed": seed, "drag": drag, "model": label(m, effects, signed), "covered": cov.tolist(),
                     "n_covered": int(cov.sum()), "z": z.tolist(), "w": nm.w, "inflation": nm.inflation,
                     "seconds": secs, "refit_seconds": t_refit, "nuisance_q05_q50_q95": nuis,
                     "converged": False, "ess_per_minute": 0.0})
        extra = " nuisance " + " ".join(f"{e} {q[1]:.3g} [{q[0]:.3g}, {q[2]:.3g}]" for e, q in zip(effects, nuis))
        print(f"seed {seed} drag {drag:g} {label(m, effects, signed):16s} LAPLACE covered {cov.sum():2d}/14 w {nm.w:.3g} "
              f"inflation {nm.inflation:.3g} |z|max {np.abs(z).max():.1f} ({PARAM_NAMES[int(np.abs(z).argmax())]})"
              f"{extra if effects else ''} {secs:.0f} s", flush=True)
    return rows


def cached_fit(seed: int, drag: float, d: dict, cam, body, truth: dict):
    """The fit of a throw (pickled in the throw cache: rerunning the benchmark does not refit)."""
    import vidsim

    # keyed by the package's source digest too: a fit made by other code must not stand in (review, 5 Dec 2026)
    path = os.path.join("/tmp/vidsim_posterior_throws", f"fit_{seed}_drag{drag:g}_{vidsim.SOURCE_DIGEST[:12]}.pkl")
    if os.path.isfile(path):
        with open(path, "rb") as fh:
            return pickle.load(fh)
    guess = perturbed_guess(truth, np.random.default_rng(seed), orient_deg=10.0, omega_rel=0.2, vel_rel=0.1,
                            pos_m=0.05, grav_deg=3.0)
    fit = fit_throw(d["masks"], d["times"], cam, body, guess, {"multistart": "none"})
    with open(path + ".tmp", "wb") as fh:
        pickle.dump(fit, fh)
    os.replace(path + ".tmp", path)
    return fit


def run_throw(seed: int, drag: float, models: list[str], scfg: SamplerConfig, laplace: bool = False,
              effects: tuple[str, ...] = (), signed: bool = False, refit_nfev: int = 15) -> list[dict]:
    """Fit and sample one throw for each noise model; rows of coverage and cost."""
    d = throw_data(seed, drag)
    cam = PinholeCamera.from_dict(d["camera"])
    body = BoxBody.from_meta(d["meta"]["object"])
    truth = d["truth"]
    fit = cached_fit(seed, drag, d, cam, body, truth)
    if laplace:
        return laplace_rows(seed, drag, models, d, cam, body, fit, truth, effects, signed, refit_nfev)
    rows = []
    for m in models:
        post = rigid_posterior(d["masks"][fit.frames], fit.times, cam, body, fit.params, fit.q0, fit.t0,
                               noise=noise_config(m), sampler=scfg,
                               discrepancy=DiscrepancyConfig(effects=tuple(effects), signed=signed,
                                                             refit_nfev=refit_nfev))
        tp = to_natural(truth_params(truth, post.q_base, body.symmetries))
        S = post.samples()[:, :14]
        cov = covered(S, tp, 90.0)
        dg = post.diagnostics()
        z = (np.median(S, 0) - tp) / S.std(0)
        nuis = np.percentile(post.samples()[:, 14:], [5, 50, 95], axis=0).T.tolist()
        rows.append({"seed": seed, "drag": drag, "model": label(m, effects, signed), "covered": cov.tolist(),
                     "n_covered": int(cov.sum()), "nuisance_q05_q50_q95": nuis, "z": z.tolist(),
                     "fit_seconds": fit.seconds, "mean_iou": fit.mean_iou,
                     "converged": dg["converged"], "tau_max": dg["tau_max"], "n_steps": dg["n_steps"],
                     "seconds": dg["seconds"], "ess": dg["ess"], "ess_per_minute": dg["ess_per_minute"],
                     "w": post.noise.w, "r2": post.noise.r2, "multimodal": post.multimodal})
        print(f"seed {seed} drag {drag:g} {label(m, effects, signed):13s} covered {cov.sum():2d}/14 converged {dg['converged']!s:5s} "
              f"tau {dg['tau_max']:.0f} steps {dg['n_steps']} posterior {dg['seconds']:.0f} s "
              f"(fit {fit.seconds:.0f} s) ESS/min {dg['ess_per_minute']:.0f} w {post.noise.w:.3g} "
              f"r2 {post.noise.r2:.3f} |z|max {np.abs(z).max():.1f} ({PARAM_NAMES[int(np.abs(z).argmax())]})",
              flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(1000, 1020)))
    ap.add_argument("--drag", type=float, default=0.0)
    ap.add_argument("--noise", nargs="+", default=["sandwich"])
    ap.add_argument("--max-steps", type=int, default=3000)
    ap.add_argument("--walkers", type=int, default=32)
    ap.add_argument("--json", default="")
    ap.add_argument("--laplace", action="store_true", help="Gaussian approximation only (no MCMC)")
    ap.add_argument("--discrepancy", nargs="*", default=[],
                    help="gap-library effects sampled as nuisance parameters (e.g. quadratic_drag)")
    ap.add_argument("--signed", action="store_true", help="nuisance prior [-upper, upper] instead of [0, upper]")
    ap.add_argument("--refit-nfev", type=int, default=15, help="budget of the mode's refit with the nuisance free")
    a = ap.parse_args()
    scfg = SamplerConfig(n_walkers=a.walkers, max_steps=a.max_steps, chunk=100, min_steps=300)
    t = time.perf_counter()
    rows = []
    for s in a.seeds:
        rows += run_throw(s, a.drag, a.noise, scfg, a.laplace, tuple(a.discrepancy), a.signed, a.refit_nfev)
        if a.json:  # strict JSON: a non-finite figure is null
            write_json(a.json, rows)
    print(f"--- {len(a.seeds)} throws, drag {a.drag:g}, total {time.perf_counter() - t:.0f} s (shared 2-core machine)")
    for m in (label(x, tuple(a.discrepancy), a.signed) for x in a.noise):
        r = [x for x in rows if x["model"] == m]
        cov = np.array([x["covered"] for x in r])
        per_param = cov.mean(0)
        print(f"{m:13s} {'LAPLACE ' if a.laplace else ''}coverage of 90 % intervals: {cov.mean():.3f} ({cov.sum()}/{cov.size} pairs); "
              f"converged {sum(x['converged'] for x in r)}/{len(r)}; posterior time per throw median "
              f"{np.median([x['seconds'] for x in r]):.0f} s; ESS/min median {np.median([x['ess_per_minute'] for x in r]):.0f}")
        print("   per parameter: " + " ".join(f"{n} {c:.2f}" for n, c in zip(PARAM_NAMES, per_param)))


if __name__ == "__main__":
    main()
