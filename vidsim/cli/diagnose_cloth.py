"""Stage ``diagnose_cloth``: where the gap of a cloth fit lies, which effect causes it, how far it shrinks.

``python -m vidsim.cli.diagnose_cloth paths.footage=results/footage/cloth_linen_robot
gap.paths.fit=results/cloth/select/linen/params.yaml paths.out=results/gap/cloth_linen_robot``
(plus the study's ``cloth.model.*`` and ``cloth.fit.estimate`` overrides, as the fit was run).

The cloth counterpart of ``diagnose`` (:func:`vidsim.gap.cloth_diagnose.diagnose_cloth`): reads a
swatch footage folder (frames, times, calibration, meta: the measured corner paths, size and
density; never the truth file beside it), extracts the silhouettes and angle maps from the footage
itself (as ``fit_cloth`` does), and takes the fitted parameters from ``gap.paths.fit``: a
``select_cloth`` ``params.yaml`` or a ``fit_cloth`` ``fit.yaml``. The estimated names are the fit
file's ``estimated`` when it lists them, else ``cloth.fit.estimate`` (empty: every parameter of
``cloth.fit.space``, as ``fit_cloth`` reads it). The diagnosis refits those on
the training frames, films a twin of the fit for the noise floor, screens the cloth library
(``gap.cloth.diagnose.*``: :class:`vidsim.gap.cloth_diagnose.ClothDiagnoseConfig`), refits the best
candidates and judges them on held-out frames; by default (``gap.cloth.diagnose.region: split``)
twice, the frame-timing, imaging and grip candidates also on the pixels near the gripped corners,
whose outline follows the measured corner paths. Writes ``diagnosis.json`` (verdict, named effects,
held-out gap before/after, floor, screen, refits, where: per phase, part, region and metric term),
``diagnosis.png`` and ``diagnosis.rrd``; all or nothing (a temporary folder renamed at the end).

What it finds on the study's MuJoCo fabrics is in docs/gap.md ("Diagnosing the cloth study's
fits"); on the withheld-effect twin cases (``gap_cloth_suite``) the blind cloth diagnosis names
three withheld effects of ten (time offset, time jitter, grip slip; none of the dynamics effects
wind, gravity tilt, damping, anisotropic stretch), so read its verdicts with that record in mind.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf, open_dict

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import ClothStageError, feature_settings, load_trial, params_from_dict
from vidsim.cli.gap_common import write_diagnosis
from vidsim.errors import ConfigError
from vidsim.log.progress import Progress
from vidsim.io.footage import load_yaml


def read_fit(path: str, cfg: DictConfig):
    """``(ClothParams, estimated names)`` of a ``params.yaml``/``fit.yaml`` (names a bad file or field)."""
    from vidsim.cloth import ESTIMATED_NAMES

    p = Path(path)
    if not p.is_file():
        raise ClothStageError(f"{p}: fit file is missing (give select_cloth's params.yaml or fit_cloth's fit.yaml)")
    doc = load_yaml(p, ClothStageError, mapping=True)
    if not isinstance(doc.get("params"), dict):
        raise ClothStageError(f"{p}: field 'params' is missing (expected select_cloth's params.yaml or fit_cloth's fit.yaml)")
    params = params_from_dict(doc["params"], str(p))
    # the fit file's own list; else the config's, where empty means the whole space (as in fit_cloth)
    est = doc.get("estimated") or list(cfg.cloth.fit.estimate) or list(cfg.cloth.fit.space)
    bad = [n for n in est if n not in ESTIMATED_NAMES]
    if bad:
        raise ClothStageError(f"{p}: estimated name(s) {bad} are not cloth parameters; known: {list(ESTIMATED_NAMES)}")
    return params, [str(n) for n in est]


def run(cfg: DictConfig) -> None:
    from vidsim.cli.gap_cloth_suite import settings
    from vidsim.gap.cloth_diagnose import ClothDiagnoseConfig, ClothTrialInput, diagnose_cloth
    from vidsim.gap.cloth_model import ClothGapError
    from vidsim.gap.cloth_suite import background_noise
    from vidsim.io.footage import read_footage

    if not cfg.paths.footage:
        raise ClothStageError("paths.footage is empty: give the cloth footage folder to diagnose")
    if not cfg.gap.paths.fit:
        raise ClothStageError("gap.paths.fit is empty: give select_cloth's params.yaml or fit_cloth's fit.yaml")
    fo = Path(cfg.paths.footage)
    if not fo.is_dir():
        raise ClothStageError(f"{fo}: footage folder is missing")
    params, estimated = read_fit(cfg.gap.paths.fit, cfg)
    dcfg = settings(ClothDiagnoseConfig, OmegaConf.to_container(cfg.gap.cloth.diagnose, resolve=True),
                    "gap.cloth.diagnose")
    try:
        dcfg.validate()
    except ClothGapError as e:
        raise ConfigError(str(e)) from e
    mc = cfg.cloth.model
    stride, most = int(mc.frame_stride), int(mc.max_frames)
    # every frame up to the last one the fit compared: the model is driven by the full-rate corner
    # paths and compares every stride-th frame, as the fit did
    full_cfg = cfg.copy()
    with open_dict(full_cfg):
        full_cfg.cloth.model.frame_stride = 1
        full_cfg.cloth.model.max_frames = 0
    tr = load_trial(fo, full_cfg)
    if tr.skirt is not None:
        raise ClothStageError(f"{fo}/meta.yaml: object.kind is skirt; the cloth diagnosis takes swatch footage")
    n = tr.features.n_frames if most <= 0 else min(tr.features.n_frames, (most - 1) * max(1, stride) + 1)
    tr = tr.strided(1, n)
    fp = read_footage(fo)
    bg = np.asarray(fp.meta["background_frames"], int)
    noise = background_noise(fp.frames[bg].astype(float)) if bg.size >= 2 else 2.0
    f = tr.features
    try:
        trial = ClothTrialInput(f.sil, tr.times, tr.corner_paths, tr.camera, tr.projector, tr.size, tr.density, noise,
                                f.theta, f.mask)
    except ClothGapError as e:
        raise ClothStageError(f"{fo}: {e}") from e
    # steps of one pass (a split diagnosis runs two: near the grips, on the whole outline); an
    # estimate, as the second selection step and the joint pairs run only when needed
    n_pass = 2 if dcfg.region == "split" else 1
    prog = Progress(n_pass * (6 + dcfg.top_k + int(dcfg.pairs)), "diagnose_cloth steps", enabled=cfg.log.progress)
    print(f"diagnose_cloth {fo.name}: {f.sil.shape[0]} frames (frame stride {stride}), {mc.resolution}x"
          f"{mc.resolution} model, base {estimated}", file=sys.stderr, flush=True)
    # each finished pass (near the grips, the outline) is kept here until the report is written: a
    # killed stage resumes after its last finished pass
    out = Path(cfg.paths.out)
    ckpt = out.with_name(f".{out.name}.passes")
    try:
        d = diagnose_cloth(trial, params, estimated, resolution=int(mc.resolution), frame_stride=stride,
                           settle_s=float(mc.settle_s), settle_bath=float(mc.settle_bath), cfg=dcfg,
                           feature_settings=feature_settings(cfg), alpha=float(cfg.cloth.fit.alpha),
                           progress=lambda s: prog.update(note=s), checkpoint=ckpt)
    except ClothGapError as e:
        raise ClothStageError(f"{cfg.gap.paths.fit} on {fo}: {e}") from e
    inputs = {"footage": str(fo), "fit": str(cfg.gap.paths.fit), "estimated": estimated,
              "model": OmegaConf.to_container(mc, resolve=True)}
    write_diagnosis(d, out, inputs, trial.sil, "diagnose_cloth", fo.name, cfg.log.rerun,
                    floor_label="noise floor (a twin of the fit, filmed and segmented)")
    shutil.rmtree(ckpt, ignore_errors=True)


main = stage_app("diagnose_cloth", run)

if __name__ == "__main__":
    main()
