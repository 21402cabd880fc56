"""Stage ``score_rigid``: the ONLY reader of a throw's truth; scores the fit and the segmentation.

``python -m vidsim.cli.score_rigid paths.footage=results/footage/rigid_101 paths.out=results/rigid/101``
reads ``<footage>.truth.yaml`` and ``<footage>.truth_masks.npz`` (beside the footage folder),
``fit.yaml`` and ``masks.npz`` (``<paths.out>/`` or ``rigid.paths.fit`` / ``rigid.paths.masks``) and
writes ``score.yaml``: errors of orientation (degrees, modulo the body's symmetry), angular velocity
and velocity (relative), position (relative to the range), gravity direction (degrees), mean IoU of
the fitted silhouettes against the ground-truth masks and against the footage's silhouettes, the
segmentation's IoU against the ground truth, and which criteria of the issue are met.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli._rigid import RigidStageError, read_fit, read_masks
from vidsim.io.atomic import write_yaml
from vidsim.io.footage import read_calibration, read_truth, truth_path
from vidsim.rigid.evaluate import CRITERIA, score
from vidsim.rigid.fit import silhouette_iou
from vidsim.video.segment import mask_iou


def run(cfg: DictConfig) -> None:
    if not cfg.paths.footage:
        raise RigidStageError("paths.footage is empty: give the footage folder of the throw")
    footage = Path(cfg.paths.footage)
    out = Path(cfg.paths.out)
    truth = read_truth(footage)
    for k in ("t0", "position", "quaternion", "velocity", "omega_world", "tilt", "roll"):
        if k not in truth:
            raise RigidStageError(f"{truth_path(footage)}: missing field '{k}'")
    gt_path = footage.parent / f"{footage.name}.truth_masks.npz"
    gt, gt_times = read_masks(gt_path)
    res, body = read_fit(cfg.rigid.paths.fit or out / "fit.yaml")
    masks, _ = read_masks(cfg.rigid.paths.masks or out / "masks.npz")
    if abs(res.t0 - float(truth["t0"])) > 1e-9:
        raise RigidStageError(f"fit t0 = {res.t0} differs from the truth's t0 = {truth['t0']}: the errors would "
                              "compare states at different times")
    cam = read_calibration(footage / "calibration.yaml")["camera"]
    iou_gt = silhouette_iou(res.params, res.q0, body, cam, res.times, res.t0, gt[res.frames], res.hmax, res.gravity)
    s = score(res, truth, body, iou_gt)
    throw = np.flatnonzero(gt.reshape(len(gt), -1).any(1))
    seg = mask_iou(masks[throw], gt[throw])
    eff = truth.get("effects", {})
    on = {k: v for k, v in eff.items() if (np.any(np.asarray(v, float) != 0))}
    doc = {
        "case": out.name, "seed": truth.get("seed"), "effects_on": on,
        "success": s["success"], "pass": s["pass"], "criteria": dict(CRITERIA),
        "errors": {k: float(s[k]) for k in ("orientation_deg", "omega_rel", "position_rel_range", "velocity_rel",
                                              "gravity_deg", "mean_iou", "mean_iou_footage")},
        "iou_truth_per_frame": np.asarray(iou_gt).tolist(),
        "segmentation": {"mean_iou": float(seg.mean()), "min_iou": float(seg.min()), "frames": int(throw.size)},
        "fit": {"seconds": res.seconds, "n_starts": res.n_starts, "ambiguous": res.ambiguous,
                "iterations": len(res.history)},
        "truth": str(truth_path(footage)),
    }
    write_yaml(out / "score.yaml", doc)
    e = doc["errors"]
    print(f"score_rigid {out.name}: success={s['success']} rot {e['orientation_deg']:.2f} deg, omega "
          f"{100 * e['omega_rel']:.2f} %, X {100 * e['position_rel_range']:.2f} %, V {100 * e['velocity_rel']:.2f} %, "
          f"g {e['gravity_deg']:.2f} deg, IoU(gt) {e['mean_iou']:.3f}, segmentation IoU {seg.mean():.3f}")


main = stage_app("score_rigid", run)

if __name__ == "__main__":
    main()
