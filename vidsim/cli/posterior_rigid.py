"""Stage ``posterior_rigid``: how sure the rigid fit is (emcee on the silhouette likelihood).

``python -m vidsim.cli.posterior_rigid paths.footage=results/footage/rigid_throw101
posterior.paths.fit=results/rigid/throw101/fit.yaml posterior.paths.masks=results/rigid/throw101/masks.npz
paths.out=results/posterior/rigid/throw101``

Writes ``summary.csv`` (point estimate, 5/50/95 % and sd per parameter, angles in degrees),
``posterior.yaml`` (diagnostics: autocorrelation times, ``converged``, ESS, noise model,
multimodality flag, correlations), ``corner.png``, ``correlation.png``, ``chain.npz`` (resumable:
a killed run continues from its last checkpoint, and replays its start refit and noise calibration
from ``.calibration.checkpoint/calibration.jsonl`` in the staging folder, or, killed during the
calibration, the calibration's evaluations from ``calibration_points.jsonl`` beside it
(:func:`calibration_log`; removed with whatever the logs moved aside when the run finishes) and ``posterior.rrd`` (footage with the observed
silhouette and the fraction of posterior draws covering each pixel; per-frame mismatch at the mode
as scalars). Never reads truth.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli._rigid import body_from_meta, read_fit, read_masks
from vidsim.config import to_plain
from vidsim.errors import ConfigError
from vidsim.io.atomic import replace_dir, write_text, write_yaml
from vidsim.io.footage import read_calibration, read_footage
from vidsim.log import make_logger
from vidsim.log.progress import Progress
from vidsim.posterior.figures import corner_figure, correlation_figure
from vidsim.posterior.rigid import DiscrepancyConfig, FrameLoss, NoiseConfig, RigidPriorConfig, rigid_posterior
from vidsim.posterior.sampler import PosteriorError, SamplerConfig
from vidsim.report.figures import save_figure
from vidsim.rigid.silhouette import render_coverage


def summary_csv(rows: list[dict]) -> str:
    """CSV text of the per-parameter summary rows."""
    cols = ["name", "unit", "point", "q05", "median", "q95", "mean", "sd"]
    lines = [",".join(cols)]
    for r in rows:
        lines.append(",".join(str(r[c]) if c in ("name", "unit") else f"{r[c]:.9g}" for c in cols))
    return "\n".join(lines) + "\n"


def calibration_log(tmp: Path) -> Path:
    """Where the start refit and noise calibration are logged: a checkpoint folder of its own in
    the staging folder ``tmp``, so that the log and what it moves aside after an input change
    (``calibration.stale-<k>.jsonl``) leave together (:func:`finish`)."""
    return tmp / ".calibration.checkpoint" / "calibration.jsonl"


def finish(tmp: Path, out: Path) -> None:
    """Drop the checkpoints (the calibration log's folder; a log an earlier version kept in ``tmp``
    itself, with its stale copies) and put ``tmp`` in the place of ``out``."""
    shutil.rmtree(calibration_log(tmp).parent, ignore_errors=True)
    for left in tmp.glob("calibration*.jsonl"):
        left.unlink()
    replace_dir(tmp, out)


def run(cfg: DictConfig) -> None:
    pc = cfg.posterior
    rc = pc.rigid
    for key in ("fit", "masks"):
        if not pc.paths[key]:
            raise ConfigError(f"posterior.paths.{key} is empty: give the rigid stage's {key} file")
    if not cfg.paths.footage:
        raise ConfigError("paths.footage is empty: give the footage folder of the throw (meta.yaml, calibration)")
    disc = DiscrepancyConfig(effects=tuple(rc.discrepancy), upper=dict(rc.discrepancy_upper),
                             refit_nfev=int(rc.discrepancy_refit_nfev), signed=bool(rc.discrepancy_signed))
    try:
        disc.validate()
    except PosteriorError as e:
        raise ConfigError(f"posterior.rigid.{e}") from None
    out = Path(cfg.paths.out)
    fit, body = read_fit(pc.paths.fit)
    masks, times = read_masks(pc.paths.masks)
    fo = read_footage(cfg.paths.footage)
    cam = read_calibration(cfg.paths.calibration)["camera"] if cfg.paths.calibration else fo.camera
    if masks.shape[0] <= int(np.max(fit.frames)):
        raise ConfigError(f"{pc.paths.masks}: has {masks.shape[0]} frames but the fit uses frame {int(np.max(fit.frames))}")
    gravity = body_from_meta(fo.meta, f"{fo.path}/meta.yaml")[1]  # checked: a finite magnitude > 0
    if masks.shape[1:] != (cam.height, cam.width):
        raise ConfigError(f"posterior.rigid.paths.masks = {pc.paths.masks}: masks are {masks.shape[2]}x{masks.shape[1]} "
                          f"but the camera is {cam.width}x{cam.height} (masks of another footage?)")
    obs = masks[fit.frames]
    alts = [{"params": c.params, "quaternion": c.q_base} for i, c in enumerate(fit.alternatives)
            if i in set(fit.distinct)] if fit.distinct else [
        {"params": c.params, "quaternion": c.q_base} for c in fit.alternatives]
    noise = NoiseConfig(model=rc.noise, n_design=rc.n_design, design_iters=rc.design_iters,
                        hac_bandwidth=rc.hac_bandwidth, holdout_confidence=float(rc.holdout_confidence))
    try:
        noise.validate()
    except PosteriorError as e:
        raise ConfigError(f"posterior.rigid ({e})") from None
    prior = RigidPriorConfig(rc.prior_position_m, rc.prior_rotation_deg, rc.prior_velocity_mps,
                             rc.prior_omega_radps, rc.prior_gravity_deg)
    scfg = SamplerConfig(n_walkers=rc.n_walkers, chunk=rc.chunk, min_steps=rc.min_steps, max_steps=rc.max_steps,
                         min_tau_multiple=rc.min_tau_multiple, seed=rc.seed)
    tmp = out.with_name(f".{out.name}.part")  # kept on a kill: its chain.npz is resumed
    tmp.mkdir(parents=True, exist_ok=True)
    prog = Progress(int(np.ceil(rc.max_steps / rc.chunk)), "posterior_rigid chain chunks", enabled=cfg.log.progress)
    with make_logger(tmp / "posterior.rrd", "vidsim.posterior_rigid", cfg.log.rerun) as lg:

        def on_chunk(info: dict) -> None:
            lg.set_iter(int(info["step"]))
            lg.scalar("chain/tau_max", info["tau_max"] if np.isfinite(info["tau_max"]) else 0.0)
            lg.scalar("chain/acceptance", info["acceptance"])
            prog.update(note=f"step {info['step']} tau_max {info['tau_max']:.0f} acceptance {info['acceptance']:.2f}")

        post = rigid_posterior(obs, fit.times, cam, body, fit.params, fit.q0, fit.t0, alts, noise, prior, scfg,
                               str(tmp / "chain.npz"), on_chunk, rc.distinct_deg, rc.multimodal_ratio,
                               gravity=gravity, discrepancy=disc, calibration_path=str(calibration_log(tmp)))
        diag = post.diagnostics()
        # per frame: footage, observed silhouette, fraction of posterior draws covering each pixel
        S = post.samples(natural=False)
        rng = np.random.default_rng(rc.seed)
        draws = S[rng.choice(len(S), size=min(int(pc.draws_logged), len(S)), replace=False)]
        cover = np.zeros(obs.shape, np.float32)
        n_ok = 0
        fl = FrameLoss(body, cam, fit.times, obs, fit.t0, post.q_base, gravity=gravity, effects=disc.effects)
        for p in draws:
            tq = fl.trajectory(p)
            if tq is not None:
                cover += render_coverage(tq[0], tq[1], body.box_vertices(), cam) > 0.5
                n_ok += 1
        cover /= max(n_ok, 1)
        e_mode = post.noise.loss_min
        e_frames = fl(post.noise.center)
        for k, f in enumerate(fit.frames):
            lg.set_frame(int(f))
            lg.image("footage/camera/image", fo.frames[int(f)])
            lg.mask("footage/camera/mask", obs[k])
            lg.image("posterior/camera/draw_fraction", (255 * cover[k]).astype(np.uint8))
            if e_frames is not None:
                lg.scalar("posterior/mismatch_at_mode_px", float(e_frames[k]))
            lg.scalar("posterior/uncertain_pixels", float(np.sum((cover[k] > 0.05) & (cover[k] < 0.95))))
        lg.text("posterior/summary", summary_csv(post.summary))
        write_text(tmp / "summary.csv", summary_csv(post.summary))
        write_yaml(tmp / "posterior.yaml", {
            "diagnostics": diag, "names": post.names, "units": post.units,
            "correlation": np.round(post.corr, 4).tolist(), "loss_at_mode_px": float(e_mode),
            "q_base": post.q_base.tolist(), "note": "rx ry rz: rotation (degrees, body axes) from q_base",
            "config": to_plain(pc)})
        nat_point = np.array([r["point"] for r in post.summary])
        warn = ", ".join(w for w, bad in ((f"chain NOT converged ({diag['n_steps']} steps, < 50 tau of "
                                            f"{diag['tau_max']:.0f})", not diag["converged"]),
                                           ("multimodal", bool(diag.get("multimodal")))) if bad)
        save_figure(corner_figure(post.samples(), post.names, post.units, nat_point, flags=warn), tmp / "corner.png")
        save_figure(correlation_figure(post.corr, post.names), tmp / "correlation.png")
    finish(tmp, out)
    print(f"posterior_rigid: converged {diag['converged']} (steps {diag['n_steps']}, tau_max {diag['tau_max']:.0f}), "
          f"ESS {diag['ess']:.0f}, multimodal {diag['multimodal']}, {diag['seconds']:.0f} s")


main = stage_app("posterior_rigid", run)

if __name__ == "__main__":
    main()
