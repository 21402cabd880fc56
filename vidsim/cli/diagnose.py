"""Stage ``diagnose``: where the gap of a rigid fit lies, which effect causes it, how far it shrinks.

``python -m vidsim.cli.diagnose paths.footage=results/footage/rigid_drag103
gap.paths.masks=results/rigid/drag103/masks.npz gap.paths.fit=results/rigid/drag103/fit.yaml
paths.out=results/gap/drag103``. Reads the footage folder (times, calibration, meta: the body), the
silhouettes and the fit; never the truth. Writes ``diagnosis.json`` (verdict, named effects with
held-out gap before/after, noise floor, closure, fitted effect parameters with 95 % intervals,
screen, where: per phase / part / region), ``diagnosis.png`` and ``diagnosis.rrd``.
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli.gap_common import diagnose_config, write_diagnosis
from vidsim.errors import VidsimError
from vidsim.gap.rigid_model import GapError
from vidsim.log.progress import Progress


class DiagnoseError(VidsimError):
    """Bad input to the diagnose stage (missing file, mismatched shapes); names the file."""


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
    dcfg = diagnose_config(cfg.gap.diagnose)
    prog = Progress(4 + dcfg.top_k + int(dcfg.pairs), "diagnose steps", enabled=cfg.log.progress)
    try:
        d = diagnose_rigid(masks, times, cam, body, fit, dcfg, progress=lambda s: prog.update(note=s))
    except GapError as e:
        raise DiagnoseError(f"{cfg.gap.paths.fit}: {e}") from e
    inputs = {"footage": str(fo), "masks": str(cfg.gap.paths.masks), "fit": str(cfg.gap.paths.fit)}
    write_diagnosis(d, Path(cfg.paths.out), inputs, masks, "diagnose", fo.name, cfg.log.rerun)


main = stage_app("diagnose", run)

if __name__ == "__main__":
    main()
