"""Stage ``reality_cloth``: film one fabric x motion trial of the hanging swatch under stripes.

``python -m vidsim.cli.cloth_reality paths.calibration=results/calibration/cloth/calibration.yaml
paths.out=results/footage/cloth_linen_exp1 cloth.reality.fabric=linen cloth.reality.motion=exp1``

Reality (:mod:`vidsim.reality.cloth`, MuJoCo flex cloth with its own per-face air model; or the
``twin``: the estimator's simulator on a finer mesh with ``cloth.reality.twin_params``) moves the
swatch, or, with ``cloth.reality.object=skirt``, dresses the skipping body of ``cloth.skirt`` with a
MuJoCo skirt (seed Figure 9); :func:`vidsim.clothfit.film.film_cloth` films it with the *true* camera and projector
(pyrender, shadows, falloff, noise, blur; optional lens term, projector misalignment, motion
blur). The footage folder carries the *estimated* calibration from the calibration stage and, in
``meta.yaml``, the known inputs: the measured corner paths (motion capture) and swatch size, or for
a skirt the body's motion (waist pose and leg capsules per frame) and the skirt's cut; the areal
density, the projected stripe pattern and which frames show the empty scene. Everything else
(fabric, true parameters, true corner paths, effects) goes to the truth file beside the folder.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import ClothStageError
from vidsim.cloth import ClothParams
from vidsim.clothfit.film import ClothFilmError, FilmSettings, film_cloth, rotate_about_center, twin_swatch
from vidsim.clothfit.rig import SkirtBody
from vidsim.config import camera_from_config, projector_from_config, to_plain
from vidsim.io.atomic import replace_dir
from vidsim.io.footage import read_calibration, recording_path, truth_path, write_footage, write_truth
from vidsim.log import make_logger
from vidsim.log.progress import Progress
from vidsim.reality.cloth import (
    SKIRT_SHAPE,
    corner_paths,
    fabric_profile,
    simulate_skirt,
    simulate_swatch,
    skirt_motion,
    swatch_motion,
)
from vidsim.render.projector import Projector
from vidsim.report.figures import contact_sheet
from vidsim.video.camera import PinholeCamera

SIZE_M = 0.3


def _film_settings(rc) -> FilmSettings:
    """``cloth.reality``'s settings checked by their config names (before anything is simulated)."""
    for key, ok, expected in (("fps", rc.fps > 0, "> 0 frames per second"), ("n_frames", rc.n_frames >= 1, ">= 1"),
                              ("resolution", rc.resolution >= 3, ">= 3 vertices per side"),
                              ("settle_s", rc.settle_s >= 0, ">= 0 s")):
        if not ok:
            raise ClothStageError(f"cloth.reality.{key} = {rc[key]!r} is not valid: expected {expected}")
    try:
        return FilmSettings(n_background=int(rc.n_background), albedo=float(rc.albedo), noise_sigma=float(rc.noise_sigma),
                            blur_sigma_px=float(rc.blur_sigma_px), jpeg_quality=int(rc.jpeg_quality),
                            motion_blur=int(rc.motion_blur), exposure=float(rc.exposure))
    except ClothFilmError as e:
        raise ClothStageError(str(e).replace("FilmSettings.", "cloth.reality.")) from None


def run(cfg: DictConfig) -> None:
    out = Path(cfg.paths.out)
    fs = _film_settings(cfg.cloth.reality)
    if not cfg.paths.calibration:
        raise ClothStageError("paths.calibration is empty: give the cloth scene's calibration.yaml")
    est = read_calibration(cfg.paths.calibration)
    if "projector" not in est:
        raise ClothStageError(f"{cfg.paths.calibration}: field 'projector' is missing (calibrate with projector=cloth)")
    rc = cfg.cloth.reality
    pc = cfg.cloth.projector
    cam = camera_from_config(cfg.cloth.camera)
    lens = PinholeCamera(cam.K, cam.R, cam.t, cam.width, cam.height, cam.dist + np.array([rc.lens_k1, 0, 0, 0, 0]))
    proj_true = rotate_about_center(projector_from_config(pc), float(rc.projector_misalign_deg))
    projector = Projector(proj_true, period_px=float(pc.period_px), power=float(pc.power), ambient=float(pc.ambient))
    rng = np.random.default_rng([int(cfg.seed), int(rc.seed), sum(map(ord, f"{rc.fabric}/{rc.motion}/{rc.kind}"))])
    obj = str(rc.object)
    if obj not in ("swatch", "skirt"):
        raise ClothStageError(f"cloth.reality.object = {obj!r} is not valid: expected 'swatch' or 'skirt'")
    effects = OmegaConf.to_container(rc.effects, resolve=True) or {}
    fe = rc.get("fabric_effects", None)
    extra = ((OmegaConf.to_container(fe, resolve=True) if fe is not None else None) or {}).get(str(rc.fabric), {})
    for k, v in extra.items():
        effects[k] = {**effects.get(k, {}), **v}
    if obj == "skirt":
        sim = _skirt_reality(cfg, effects, rng)
    elif rc.kind == "mujoco":
        sim = _swatch_mujoco(rc, effects, rng)
    elif rc.kind == "twin":
        sim = _swatch_twin(rc)
    else:
        raise ClothStageError(f"cloth.reality.kind = {rc.kind!r} is not valid: expected 'mujoco' or 'twin'")
    V, F, times, cp, density, fps, body, truth = sim
    frames = film_cloth(V, F, lens, projector, rng, fs)
    nb = int(rc.n_background)
    all_times = np.concatenate([times[0] - (nb - np.arange(nb)) / fps, times])
    meta = {
        "scene": "cloth", "fps_nominal": fps, "background_frames": list(range(nb)),
        "areal_density": float(density),
        "projector_pattern": {"period_px": float(pc.period_px), "power": float(pc.power), "ambient": float(pc.ambient),
                              "orientation": "horizontal stripes"},
    }
    if body is None:
        meta.update({"object": {"kind": "swatch", "gripped": "two top corners"}, "size_m": SIZE_M,
                     "corner_paths": np.round(np.asarray(cp, float), 6).tolist(), "trial": str(rc.motion)})
    else:
        meta.update({"object": {"kind": "skirt", "held": "waistband on the body's waist; legs are capsules"},
                     "body": body.to_meta(), "trial": f"skirt/{cfg.cloth.skirt.motion}"})
    tmp = out.with_name(f".{out.name}.part")
    shutil.rmtree(tmp, ignore_errors=True)
    prog = Progress(len(frames), "reality_cloth log", enabled=cfg.log.progress)
    with make_logger(recording_path(out), "vidsim.reality_cloth", cfg.log.rerun) as lg:
        for i, img in enumerate(frames):
            lg.set_frame(i)
            lg.image("footage/camera/image", img)
            if i >= nb:
                lg.mesh3d("truth/cloth", V[i - nb], F, color=(0.8, 0.6, 0.3))
                lg.points3d("known/corners" if body is None else "known/waistband", cp[i - nb], radii=0.008)
            prog.update()
        write_footage(tmp, frames, all_times, est, meta)
        contact_sheet(frames[nb:], tmp / "contact_sheet.png")
    truth.update({"camera": cam.to_dict(), "projector": proj_true.to_dict(), "effects": effects,
                  "config": to_plain(cfg.cloth)})
    replace_dir(tmp, out, stale=(truth_path(out),))
    write_truth(out, _plain(truth))
    print(f"reality_cloth: wrote {out}", flush=True)


def _skirt_reality(cfg: DictConfig, effects: dict, rng: np.random.Generator) -> tuple:
    """MuJoCo skirt on the skipping body: (V, F, times, waist ring, density, fps, body, truth)."""
    rc, sk = cfg.cloth.reality, cfg.cloth.skirt
    if rc.kind != "mujoco":
        raise ClothStageError(f"cloth.reality.object=skirt needs cloth.reality.kind=mujoco, got {rc.kind!r}")
    print(f"reality_cloth: mujoco {rc.fabric} skirt on '{sk.motion}', {sk.n_frames} frames at {sk.fps} Hz", flush=True)
    fabric = fabric_profile(str(rc.fabric))
    run_ = simulate_skirt(fabric, skirt_motion(str(sk.motion)), effects, rng, n_frames=int(sk.n_frames),
                          fps=float(sk.fps), rings=int(sk.rings), around=int(sk.around), settle=float(rc.settle_s))
    if not run_.ok:
        raise ClothStageError(f"reality_cloth {rc.fabric}/skirt: MuJoCo reality failed: {run_.failure}")
    col = run_.colliders
    body = SkirtBody(col["waist_pos"], col["waist_rot"], col["capsules"], float(col["radii"][0]), **SKIRT_SHAPE)
    truth = {"kind": "mujoco", "fabric": fabric, **{k: v for k, v in run_.truth.items() if k != "fabric"}}
    return (run_.vertices, run_.faces, run_.times, col["waist_ring"], fabric["areal_density"], float(sk.fps), body,
            truth)


def _swatch_mujoco(rc: DictConfig, effects: dict, rng: np.random.Generator) -> tuple:
    """MuJoCo swatch of a fabric along a motion: (V, F, times, measured corners, density, fps, None, truth)."""
    print(f"reality_cloth: mujoco {rc.fabric}/{rc.motion}, {rc.n_frames} frames at {rc.fps} Hz", flush=True)
    fabric = fabric_profile(str(rc.fabric))
    run_ = simulate_swatch(fabric, swatch_motion(str(rc.motion)), effects, rng, n_frames=int(rc.n_frames),
                           fps=float(rc.fps), resolution=int(rc.resolution), size=SIZE_M, settle=float(rc.settle_s),
                           settle_bath=float(rc.settle_bath))
    if not run_.ok:
        raise ClothStageError(f"reality_cloth {rc.fabric}/{rc.motion}: MuJoCo reality failed: {run_.failure}")
    truth = {"kind": "mujoco", "fabric": fabric, **{k: v for k, v in run_.truth.items() if k != "fabric"}}
    return (run_.vertices, run_.faces, run_.times, run_.corner_paths_measured, fabric["areal_density"], float(rc.fps),
            None, truth)


def _swatch_twin(rc: DictConfig) -> tuple:
    """The twin: the estimator's simulator, finer mesh, known parameters (same tuple as above)."""
    print(f"reality_cloth: twin/{rc.motion}, {rc.n_frames} frames at {rc.fps} Hz", flush=True)
    motion = swatch_motion(str(rc.motion))
    tp = OmegaConf.to_container(rc.twin_params, resolve=True)
    params = ClothParams(**tp)
    V, F, cp, ok, failure = twin_swatch(params, lambda t: corner_paths(motion, t), int(rc.n_frames), float(rc.fps),
                                        int(rc.twin_resolution), size=SIZE_M, settle_s=float(rc.settle_s),
                                        settle_bath=float(rc.settle_bath))
    if not ok:
        raise ClothStageError(f"reality_cloth twin/{rc.motion}: the twin simulation failed: {failure}")
    times = np.arange(int(rc.n_frames)) / float(rc.fps)
    truth = {"kind": "twin", "params": {k: float(v) for k, v in tp.items()}, "resolution": int(rc.twin_resolution)}
    return V, F, times, cp, params.density, float(rc.fps), None, truth


def _plain(x):
    """numpy -> plain python for YAML."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return np.round(x.astype(float), 6).tolist() if x.dtype.kind == "f" else x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x


main = stage_app("reality_cloth", run)

if __name__ == "__main__":
    main()
