"""Stage ``diagnose``: where the gap of a rigid fit lies, which effect causes it, how far it shrinks.

``python -m vidsim.cli.diagnose paths.footage=results/footage/rigid_drag103
gap.paths.masks=results/rigid/drag103/masks.npz gap.paths.fit=results/rigid/drag103/fit.yaml
paths.out=results/gap/drag103``. Reads the footage folder (times, calibration, meta: the body), the
silhouettes and the fit; never the truth. Writes ``diagnosis.json`` (verdict, named effects with
held-out gap before/after, noise floor, closure, fitted effect parameters with nominal 95 % intervals
(frame-clustered sandwich; 16 of 24 held the truth in the rigid suite: a lower bound on the uncertainty),
screen, where: per phase / part / region), ``diagnosis.png`` and ``diagnosis.rrd``.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli.gap_common import diagnose_config, write_diagnosis
from vidsim.errors import VidsimError
from vidsim.gap.rigid_model import GapError
from vidsim.log.progress import Progress


class DiagnoseError(VidsimError):
    """Bad input to the diagnose stage (missing file, mismatched shapes); names the file."""


def _check_fit_fields(fit: dict, where: str, times) -> None:
    """The fit's initial state: finite vectors of the right sizes, a non-zero quaternion and a t0
    within the footage's time span; the error names the file and field."""
    import numpy as np

    for key, n, unit in (("position", 3, "m"), ("quaternion", 4, "-"), ("velocity", 3, "m/s"),
                         ("omega_world", 3, "rad/s"), ("tilt", 1, "rad"), ("roll", 1, "rad"), ("t0", 1, "s")):
        try:
            v = np.asarray(fit[key], float).reshape(-1)
        except (TypeError, ValueError):
            raise DiagnoseError(f"{where}: field '{key}' = {fit[key]!r} is not numeric ({n} number(s), {unit})") from None
        if v.size != n or not np.all(np.isfinite(v)):
            raise DiagnoseError(f"{where}: field '{key}' = {fit[key]!r}: expected {n} finite number(s) ({unit})")
    if np.linalg.norm(np.asarray(fit["quaternion"], float)) < 1e-9:
        raise DiagnoseError(f"{where}: field 'quaternion' is zero (expected a rotation)")
    t0, span = float(fit["t0"]), (float(np.min(times)), float(np.max(times)))
    if not span[0] - 1.0 <= t0 <= span[1]:
        raise DiagnoseError(f"{where}: field 't0' = {t0} s lies outside the footage's times {span[0]:.3f}-{span[1]:.3f} s "
                            "(a fit of another footage?)")


def run(cfg: DictConfig) -> None:
    from vidsim.cli._rigid import body_from_meta, load_yaml, read_masks
    from vidsim.gap.rigid_diagnose import diagnose_rigid
    from vidsim.io.footage import read_calibration, read_meta

    if not cfg.paths.footage:
        raise DiagnoseError("paths.footage is empty: give the footage folder of the fitted throw")
    if not cfg.gap.paths.masks or not cfg.gap.paths.fit:
        raise DiagnoseError("gap.paths.masks and gap.paths.fit must name the silhouettes (masks.npz) and the fit (fit.yaml)")
    fo = Path(cfg.paths.footage)
    if not fo.is_dir():
        raise DiagnoseError(f"{fo}: footage folder is missing")
    meta = read_meta(fo / "meta.yaml")
    body, _ = body_from_meta(meta, str(fo / "meta.yaml"))
    cam = read_calibration(cfg.paths.calibration or fo / "calibration.yaml")["camera"]
    masks, times = read_masks(cfg.gap.paths.masks)
    fit = load_yaml(cfg.gap.paths.fit)
    if not isinstance(fit, dict):
        raise DiagnoseError(f"{cfg.gap.paths.fit}: expected a mapping (the fit_rigid stage's fit.yaml)")
    missing = [k for k in ("position", "quaternion", "velocity", "omega_world", "tilt", "roll", "t0") if k not in fit]
    if missing:
        raise DiagnoseError(f"{cfg.gap.paths.fit}: missing field(s) {missing} (expected the fit_rigid stage's fit.yaml)")
    _check_fit_fields(fit, str(cfg.gap.paths.fit), times)
    if masks.shape[1:] != (cam.height, cam.width):
        raise DiagnoseError(f"{cfg.gap.paths.masks}: masks are {masks.shape[2]}x{masks.shape[1]} but the camera is "
                            f"{cam.width}x{cam.height} (masks of another footage?)")
    if not masks.any():
        raise DiagnoseError(f"{cfg.gap.paths.masks}: empty silhouette in every frame: nothing to diagnose")
    dcfg = diagnose_config(cfg.gap.diagnose)
    prog = Progress(4 + dcfg.top_k + int(dcfg.pairs), "diagnose steps", enabled=cfg.log.progress)
    # each finished step (base refit, floor, screens, refits) is kept here until the report is
    # written: a killed stage resumes after its last finished step
    out = Path(cfg.paths.out)
    ckpt = out.with_name(f".{out.name}.steps")
    try:
        d = diagnose_rigid(masks, times, cam, body, fit, dcfg, progress=lambda s: prog.update(note=s),
                           checkpoint=ckpt)
    except GapError as e:
        raise DiagnoseError(f"{cfg.gap.paths.fit}: {e}") from e
    inputs = {"footage": str(fo), "masks": str(cfg.gap.paths.masks), "fit": str(cfg.gap.paths.fit)}
    write_diagnosis(d, out, inputs, masks, "diagnose", fo.name, cfg.log.rerun)
    shutil.rmtree(ckpt, ignore_errors=True)


main = stage_app("diagnose", run)

if __name__ == "__main__":
    main()
