"""Stage ``fit_rigid``: estimate a throw's initial state and gravity direction from its silhouettes.

``python -m vidsim.cli.fit_rigid paths.footage=results/footage/rigid_101 paths.out=results/rigid/101``
(silhouettes from ``<paths.out>/masks.npz`` or ``rigid.paths.masks``). Reads ONLY the footage
folder (meta.yaml: ``object``, ``gravity_magnitude``, ``initial_guess``; calibration.yaml or
``paths.calibration``) and the silhouettes; never the truth. Writes

* ``fit.yaml``: named parameters at ``t0``, IoU, alternatives and the two-solution report
  (:func:`vidsim.rigid.outputs.fit_to_dict`; read it back with ``fit_from_dict``), the frame they
  are in (``world_frame``: the calibration's world frame, the camera's when R = I, t = 0; a
  calibration with R != I or t != 0 is warned about on stderr and in ``frame_warning``);
* ``overlay.mp4`` (or ``.gif``): model silhouette (green) over the footage with the observed one (magenta);
* ``errors.png``: IoU and mismatch per frame, objective per iteration, the 3D path;
* ``rigid.rrd``: footage, observed and simulated silhouettes, per-frame errors, iterations, 3D path.

Checkpoint: every finished stage of every start is logged to ``.fit_rigid.stages.jsonl`` in the
output folder as it ends; a killed run started again replays them and continues (the same result
as an uninterrupted run); the file is removed once ``fit.yaml`` is written.
"""

from __future__ import annotations

import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli._rigid import RigidStageError, body_from_meta, fit_config, log_image, read_masks
from vidsim.io.video import write_animation
from vidsim.config.rigid import validate_rigid
from vidsim.io.atomic import write_yaml
from vidsim.rigid.fit import MIN_EXPLAINED_IOU
from vidsim.io.footage import read_calibration, read_footage
from vidsim.log import make_logger
from vidsim.log.progress import Progress
from vidsim.report.figures import save_figure
from vidsim.rigid.body import RigidBodyError
from vidsim.rigid.fit import FAIL_COST, fit_throw
from vidsim.rigid.outputs import corner_paths, fit_to_dict, is_camera_frame, overlay, simulated_masks


def _plot(res, mism: np.ndarray, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(14, 3.8))
    ax[0].plot(res.frames, res.iou, "o-", ms=3, label="IoU")
    ax[0].set_xlabel("frame")
    ax[0].set_ylabel("silhouette IoU")
    ax[0].set_title(f"per frame (mean IoU {res.mean_iou:.3f})")
    a2 = ax[0].twinx()
    a2.plot(res.frames, mism, "s-", ms=3, color="tab:red", label="mismatch")
    a2.set_ylabel("mismatched pixels", color="tab:red")
    ax[1].semilogy(np.maximum(res.history, 1e-9))
    ax[1].set_xlabel("iteration (all stages of the best start)")
    ax[1].set_ylabel("objective (px / frame)")
    ax[1].set_title(f"{res.n_starts} starts, {res.seconds:.1f} s")
    X = res.states[:, 0:3]
    ax[2].plot(X[:, 0], -X[:, 1], "o-", ms=2)
    ax[2].set_xlabel("world x (camera right when R = I), m")
    ax[2].set_ylabel("world -y (camera up when R = I), m")
    ax[2].set_title("fitted centre-of-mass path")
    ax[2].axis("equal")
    fig.tight_layout()
    save_figure(fig, path)


def with_inset(frames: np.ndarray, masks: np.ndarray, half: int = 40, zoom: int = 3) -> np.ndarray:
    """Frames (T, H, W, 3) with a ``zoom``x close-up of the object (centred on ``masks`` (T, H, W))
    in a lower corner (right, or left when the object is there), so the outlines can be compared
    in a compressed video."""
    import cv2

    out = frames.copy()
    T, H, W = masks.shape
    side = 2 * half * zoom
    if side + 8 > min(H, W):
        return out
    for k in range(T):
        ys, xs = np.nonzero(masks[k])
        if ys.size == 0:
            continue
        cy = int(np.clip(round(ys.mean()), half, H - half))
        cx = int(np.clip(round(xs.mean()), half, W - half))
        crop = frames[k, cy - half:cy + half, cx - half:cx + half]
        big = cv2.resize(crop, (side, side), interpolation=cv2.INTER_NEAREST)
        x0 = 4 if (cx > W - side - 4 - half and cy > H - side - 4 - half) else W - side - 4  # never over the object
        out[k, H - side - 4:H - 4, x0:x0 + side] = big
        cv2.rectangle(out[k], (x0 - 1, H - side - 5), (x0 + side, H - 4), (255, 255, 255), 1)
    return out


def run(cfg: DictConfig) -> None:
    validate_rigid(cfg.rigid)
    if not cfg.paths.footage:
        raise RigidStageError("paths.footage is empty: give the footage folder of the throw")
    out = Path(cfg.paths.out)
    fo = read_footage(cfg.paths.footage)
    meta_path = f"{fo.path / 'meta.yaml'}"
    body, g = body_from_meta(fo.meta, meta_path)
    if "initial_guess" not in fo.meta:
        raise RigidStageError(f"{meta_path}: missing field 'initial_guess' (position, quaternion, velocity, "
                              "omega_world, tilt, roll, t0: the user's rough initial state)")
    cam = read_calibration(cfg.paths.calibration)["camera"] if cfg.paths.calibration else fo.camera
    frame_warning = None
    if not is_camera_frame(cam):  # the guess is documented in camera axes: say how it is read, before the fit
        frame_warning = (f"the calibration ({cfg.paths.calibration or fo.path / 'calibration.yaml'}) has R != I or "
                         "t != 0: the initial guess is read, and the estimate written, in its world frame, not in "
                         "camera axes (fit.yaml's gravity_direction_camera is gravity in camera axes)")
        print(f"fit_rigid: warning: {frame_warning}", file=sys.stderr, flush=True)
    mpath = Path(cfg.rigid.paths.masks or out / "masks.npz")
    masks, times = read_masks(mpath)
    if masks.shape != fo.frames.shape[:3]:
        raise RigidStageError(f"{mpath}: masks {masks.shape} do not match the footage frames {fo.frames.shape[:3]}")
    if not np.allclose(times, fo.times, atol=1e-6):
        raise RigidStageError(f"{mpath}: 'times' differ from the footage's times.csv")
    if not masks.any():
        raise RigidStageError(f"{mpath}: empty silhouette in every one of the {len(masks)} frames: nothing to fit")
    fc = fit_config(cfg.rigid.fit, g)
    ckpt = out / ".fit_rigid.stages.jsonl"  # every finished stage of every start; removed once fit.yaml is written
    if ckpt.is_file():
        print(f"fit_rigid: resuming from {ckpt} (stages already run are replayed, not recomputed)", flush=True)
    prog = Progress(1, "fit_rigid (work units)", enabled=cfg.log.progress)

    def on_step(done: int, total: int, note: str) -> None:
        prog.total = total
        prog.update(done - prog.i, note=note)

    try:
        res = fit_throw(masks, times, cam, body, fo.meta["initial_guess"], fc, on_step=on_step, checkpoint=ckpt)
    except RigidBodyError as e:
        raise RigidStageError(f"{meta_path} / {mpath}: {e}") from e
    failed = (not np.all(np.isfinite(res.states))) or (bool(res.history) and res.history[-1] >= FAIL_COST)
    if failed:
        raise RigidStageError(f"{meta_path}: initial_guess: every start failed to simulate (diverged or left the "
                              f"view; best objective {res.history[-1] if res.history else float('nan'):.3g}): check "
                              "the guess's units (position m, velocity m/s, omega_world rad/s) and t0 (s)")
    sim = simulated_masks(res, body, cam)
    obs = masks[res.frames]
    mism = (sim ^ obs).reshape(len(sim), -1).sum(1)
    d = fit_to_dict(res, body, cam)
    d["mismatch_px"] = mism.tolist()
    d["inputs"] = {"footage": str(fo.path), "masks": str(mpath), "fit_settings": asdict(fc)}
    ov = with_inset(overlay(fo.frames[res.frames], sim, obs), obs | sim)
    fps = float(fo.meta.get("fps", 1.0 / np.median(np.diff(times))))
    write_animation(out / f"overlay.{cfg.rigid.overlay}", ov, fps)
    _plot(res, mism, out / "errors.png")
    with make_logger(out / "rigid.rrd", "vidsim.fit_rigid", cfg.log.rerun) as lg:
        lg.camera("world/camera", cam)
        corners = corner_paths(res.states, body)
        lg.lines3d("world/fit/path", [res.states[:, 0:3]])
        lg.lines3d("world/fit/corner0_path", [corners[:, 0]])
        V, F = body.mesh()
        for k, i in enumerate(res.frames):
            lg.set_frame(int(i))
            log_image(lg, "footage/camera/image", ov[k])
            lg.mask("footage/camera/mask", obs[k])
            lg.mask("sim/camera/mask", sim[k])
            lg.scalar("metric/iou", float(res.iou[k]))
            lg.scalar("metric/mismatch_px", float(mism[k]))
            lg.mesh3d("world/fit/body", corners[k], F, color=(0.1, 0.8, 0.2))
        lg.series("optim/objective", np.asarray(res.history))
    if frame_warning:
        d["frame_warning"] = frame_warning
    failed = res.mean_iou < MIN_EXPLAINED_IOU
    if failed:
        d["warning"] = (f"the fit explains little of the silhouettes (mean IoU {res.mean_iou:.3f} < {MIN_EXPLAINED_IOU}): "
                        "check the masks (segment_sheet.png), the object in meta.yaml and the initial guess")
    # the main output last: a kill while the figures are written leaves no new fit.yaml beside old figures
    write_yaml(out / "fit.yaml", d)
    ckpt.unlink(missing_ok=True)
    alt = f"; {len(res.distinct)} distinct equally good solution(s)" if res.ambiguous else \
        ("; one candidate refined: no two-solution check" if res.ambiguous is None else "")
    replay = f" ({res.replayed_stages} stages replayed from the checkpoint)" if res.replayed_stages else ""
    print(f"fit_rigid: mean IoU {res.mean_iou:.4f} over {len(res.frames)} frames, {res.n_starts} starts, "
          f"{res.seconds:.1f} s{replay}{alt} -> {out / 'fit.yaml'}")
    if failed:
        print(f"fit_rigid: warning: {d['warning']}", file=sys.stderr)


main = stage_app("fit_rigid", run)

if __name__ == "__main__":
    main()
