"""Stage ``gap_cloth_suite``: the cloth domain's withheld-effect cases -- film, fit, diagnose blind, score.

``python -m vidsim.cli.gap_cloth_suite paths.out=results/gap/cloth_suite [gap.cloth.only=[null_a,wind]]``.
Cases are the entries of ``gap.cloth.cases`` (``conf/gap/default.yaml``; add one with
``+gap.cloth.cases.mycase={label: grip_slip, seed: 9, effects: {grip_slip: {drop: 0.02}}}``);
``gap.cloth.diagnose`` and ``gap.cloth.scene`` set fields of
:class:`vidsim.gap.cloth_diagnose.ClothDiagnoseConfig` and
:class:`vidsim.gap.cloth_suite.ClothSceneConfig` (added with a ``+``:
``+gap.cloth.diagnose.top_k=1``; an unknown name stops the stage before any case runs). Writes ``cases/<name>.json`` (case, score,
diagnosis), ``suite.json`` (scores, the headline rates of :func:`vidsim.cli.gap_suite.headline`,
seconds), ``confusion.csv`` and ``confusion.png`` (true label vs first named effect),
``shrinkage.csv`` (per case: held-out gap before/after, closure, strength, and the effect's
footprint on the footage beside the sensor noise's; :func:`vidsim.cli.gap_suite.write_shrinkage`).
Only the scoring reads the truth (:func:`vidsim.gap.cloth_suite.run_case`).

Checkpoint: cases are written as they finish to ``.<out>.part/cases/``; a rerun after a kill keeps
every finished case whose stored key (its case entry, ``gap.cloth.diagnose``, ``gap.cloth.scene``
and the ``cloth`` node it films and fits with) is unchanged, as the rigid suite does. JSON files are
strict as the rigid suite's are (``cases/<name>.json``: non-finite numbers as the strings ``"nan"``,
``"inf"``, ``"-inf"``, read back as floats on resume; ``suite.json``: ``null``).
"""

from __future__ import annotations

import shutil
import sys
import time
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

import vidsim
from vidsim.cli._app import stage_app
from vidsim.cli.gap_suite import (
    CASE_NONFINITE,
    finished_or_reused,
    headline,
    select_cases,
    write_confusion,
    write_shrinkage,
)
from vidsim.errors import ConfigError
from vidsim.io.atomic import replace_dir, write_json
from vidsim.log.progress import Progress


def settings(cls: type, values: dict, where: str):
    """``cls(**values)``, with an unknown name reported as a config error naming ``where``."""
    import dataclasses

    known = {f.name for f in dataclasses.fields(cls)}
    bad = sorted(set(values) - known)
    if bad:
        raise ConfigError(f"{where}: unknown setting(s) {bad}; known: {sorted(known)}")
    return cls(**values)


def run(cfg: DictConfig) -> None:
    from vidsim.gap.cloth_diagnose import ClothDiagnoseConfig
    from vidsim.gap.cloth_model import ClothGapError
    from vidsim.gap.cloth_suite import ClothSceneConfig, case_labels, confusion, run_case, validate_case

    cc = cfg.gap.cloth
    cases, names = select_cases(cc.cases, cc.only, "gap.cloth", case_labels, ClothGapError)
    dcfg = settings(ClothDiagnoseConfig, OmegaConf.to_container(cc.diagnose, resolve=True), "gap.cloth.diagnose")
    try:
        dcfg.validate()
    except ClothGapError as e:
        raise ConfigError(str(e)) from e
    scene = settings(ClothSceneConfig, OmegaConf.to_container(cc.scene, resolve=True), "gap.cloth.scene")
    for n in names:  # every asked-for case checked before the first is filmed
        try:
            validate_case(OmegaConf.to_container(cases[n], resolve=True) if isinstance(cases[n], DictConfig)
                          else dict(cases[n]), scene)
        except ClothGapError as e:
            raise ConfigError(f"gap.cloth.cases.{n}: {e}") from e
    out = Path(cfg.paths.out)
    tmp = out.with_name(f".{out.name}.part")
    (tmp / "cases").mkdir(parents=True, exist_ok=True)
    for f in (tmp / "cases").iterdir():  # cases no longer asked for do not reach the output
        if f.stem not in names:
            f.unlink()
    # everything a case's result depends on: its entry, the diagnosis and scene settings and the
    # cloth study's devices, features and fit space (run_case reads them from cfg.cloth)
    common = {"diagnose": OmegaConf.to_container(cc.diagnose, resolve=True),
              "scene": OmegaConf.to_container(cc.scene, resolve=True),
              "cloth": OmegaConf.to_container(cfg.cloth, resolve=True), "code": vidsim.SOURCE_DIGEST}
    prog = Progress(len(names), "gap_cloth_suite cases", every_s=0.0, enabled=cfg.log.progress)
    scores: dict[str, dict] = {}
    resumed: list[str] = []
    t0 = time.perf_counter()
    for n in names:
        key = {"case": cases[n], **common}
        done = finished_or_reused(tmp / "cases", out / "cases", n, key, companions=())
        if done is not None:
            scores[n] = done
            resumed.append(n)
            prog.update(note=f"{n}: kept (finished earlier with the same settings)")
            continue
        try:
            # within a case, the fit's evaluations and the diagnosis's finished passes are kept too
            d, s, _ = run_case(cases[n], scene, dcfg, cfg.cloth, checkpoint=tmp / "running" / n)
        except ClothGapError as e:
            raise ConfigError(f"gap.cloth.cases.{n}: {e}") from e
        scores[n] = s
        write_json(tmp / "cases" / f"{n}.json", {"key": key, "case": cases[n], "score": s, "diagnosis": d.to_dict()},
                   CASE_NONFINITE)
        shutil.rmtree(tmp / "running" / n, ignore_errors=True)
        prog.update(note=f"{n}: named {s['named'] or 'nothing'} ({'ok' if s['correct'] else 'WRONG'})")
    shutil.rmtree(tmp / "running", ignore_errors=True)
    write_confusion(*confusion(scores), tmp)
    write_shrinkage(scores, tmp)
    summ = {"headline": headline(scores), "cases": scores, "seconds": time.perf_counter() - t0,
            "resumed_cases": resumed,
            "diagnose_config": OmegaConf.to_container(cc.diagnose, resolve=True),
            "scene_config": OmegaConf.to_container(cc.scene, resolve=True)}
    write_json(tmp / "suite.json", summ)
    print(f"gap_cloth_suite: {summ['headline']} in {summ['seconds']:.0f} s", file=sys.stderr)
    replace_dir(tmp, out)


main = stage_app("gap_cloth_suite", run)

if __name__ == "__main__":
    main()
