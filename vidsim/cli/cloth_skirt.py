"""Stage ``skirt_cloth``: skirt generalisation (seed Figure 9) of the fabrics' selected parameters.

``python -m vidsim.cli.cloth_skirt paths.out=results/cloth/skirt cloth.skirt.fabrics=[linen,satin]
cloth.skirt.params=[.../linen/params.yaml,...] cloth.skirt.footage=[results/footage/skirt_linen,...]``
(Snakemake fills the three lists).

Reality films a MuJoCo skirt of each fabric on a skipping body (``reality_cloth`` with
``cloth.reality.object=skirt``); the body's motion is known (``meta.yaml``: waist pose and leg
capsules per frame, like motion capture). Here the estimator's simulator dresses that motion with
each fabric's *selected* swatch parameters (never refitted on skirts), films it with the calibrated
camera and projector, and scores it against every skirt footage with the swatch metric, averaged
over ``cloth.skirt.model_fold_members`` fold-seeded starts (the footage's fold pattern is not a
known input; the videos show the first member):
``matrix.csv`` / ``matrix.png`` (rows: parameters, columns: skirt footage; the diagonal should win
each column), ``skirt.yaml`` (matrix, wins, the model skirt's settings, and per footage a
``verdicts`` entry: its own set against every other set, start by start over the fold-seeded
starts (:func:`vidsim.cli.cloth_common.paired_margins`): ``won`` when it is significantly better than
every other set, ``lost`` when some other set is significantly better than it, else ``undecided``: the
unknown initial fold pattern alone could turn the column), per fabric ``side_by_side_<fabric>.mp4`` (footage |
simulation with its own parameters), ``side_by_side.png`` (stills) and ``skirt.rrd``.

Checkpoint: every matrix cell's score and per-start errors are logged as they finish to
``.skirt_cloth.checkpoint/column<j>.jsonl`` in the output folder (:class:`vidsim.cli.cloth_common.LoggedScores`,
keyed by the parameter set's exact values, each column's log fingerprinted by its footage and
settings); a killed stage, run again, replays the logged cells and writes what an uninterrupted run
writes (the diagonal cells are simulated again: their images make the videos). The folder is removed
once ``skirt.yaml`` is written.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import (
    diagonal_wins,
    fabric_matrix,
    fabric_sets,
    irradiance_to_uint8,
    matrix_csv,
    matrix_figure,
    paired_margins,
)
from vidsim.io.atomic import write_text, write_yaml
from vidsim.io.video import write_animation
from vidsim.log import make_logger
from vidsim.report.figures import save_figure


def run(cfg: DictConfig) -> None:
    out = Path(cfg.paths.out)
    sk = cfg.cloth.skirt
    fabrics, pfiles, footage, sets = fabric_sets(cfg.cloth.skirt, "cloth.skirt")
    cells: list = []
    ckpt = out / ".skirt_cloth.checkpoint"  # the cells' logs; removed once skirt.yaml is written
    if ckpt.is_dir():
        print(f"skirt_cloth: resuming from {ckpt} (cells already scored are replayed, not simulated)", flush=True)
    E, diag = fabric_matrix(footage, sets, cfg, fabrics, "skirt_cloth", keep_diagonal=True, members=cells,
                            checkpoint=ckpt)
    n = len(fabrics)
    wins = diagonal_wins(E)
    members = int(sk.model_fold_members) if float(sk.model_fold_amplitude) > 0 else 0
    verdicts = _verdicts(E, cells, fabrics)
    tally = {k: sum(v["verdict"] == k for v in verdicts.values()) for k in ("won", "lost", "undecided")}
    note = (f"decided by the {members} fold-seeded starts (paired t, 2.5 % one-sided; a loss against any other set, Bonferroni): won {tally['won']}, lost {tally['lost']}, "
            f"undecided {tally['undecided']}") if members >= 2 else ""
    write_text(out / "matrix.csv", matrix_csv(E, fabrics))
    matrix_figure(E, fabrics, "skirt footage (skipping body)", out / "matrix.png", note)
    nv = int(sk.video_frames)
    stills = []
    with make_logger(out / "skirt.rrd", "vidsim.skirt_cloth", cfg.log.rerun) as lg:
        for fab, (tr, frames, r) in zip(fabrics, diag):
            if not r.ok:
                print(f"skirt_cloth: {fab} parameters failed on their own skirt: {r.failure}", flush=True)
                continue
            sim = np.stack([np.repeat(irradiance_to_uint8(im)[..., None], 3, axis=2) for im in r.images[0]])
            both = np.concatenate([frames, sim], axis=2)[: nv or None]
            # the frames are every frame_stride-th of the clip: play them at the clip's real speed
            write_animation(out / f"side_by_side_{fab}.mp4", both, float(sk.fps) / max(1, int(cfg.cloth.model.frame_stride)))
            stills.append((fab, both[[0, len(both) // 2, len(both) - 1]]))
            tris = _tris(tr, cfg)
            for k in range(tr.features.n_frames):
                lg.set_frame(k)
                lg.image(f"footage/{fab}/camera/image", frames[k])
                lg.mask(f"footage/{fab}/camera/silhouette", tr.features.sil[k])
                lg.image(f"sim/{fab}/camera/image", sim[k])
                lg.mesh3d(f"world/{fab}/skirt", r.positions[0][k], tris, color=(0.2, 0.5, 0.9))
                # with fold-seeded starts the error is the ensemble's mean (the images: its first member)
                lg.scalar(f"metric/{fab}/{'ensemble_mean_error' if members else 'error'}",
                          float(r.e_fold[0][k] + cfg.cloth.fit.alpha * r.e_silh[0][k]))
    _stills_figure(stills, out / "side_by_side.png")
    write_yaml(out / "skirt.yaml", {"fabrics": fabrics, "matrix": E.tolist(), "diagonal_wins": int(sum(wins)),
                                    "of": n, "wins_per_footage": dict(zip(fabrics, wins)),
                                    "verdicts": verdicts, "decided": tally, "params": pfiles,
                                    "footage": footage,
                                    "model": {"rings": int(sk.model_rings), "around": int(sk.model_around),
                                              "rest_bend": str(sk.model_rest_bend), "fold_members": members,
                                              "fold_amplitude_m": float(sk.model_fold_amplitude),
                                              "fold_seed": int(sk.model_fold_seed)}})
    shutil.rmtree(ckpt, ignore_errors=True)
    print(f"skirt_cloth: diagonal wins {sum(wins)}/{n}" + (f"; {note}" if note else ""), flush=True)


def _verdicts(E: np.ndarray, cells: list, fabrics: list[str]) -> dict:
    """Per skirt footage: does its own fabric's set win, against which rival, and is that decided by
    the fold-seeded starts (:func:`vidsim.cli.cloth_common.paired_margins`)?"""
    out = {}
    for j, m in paired_margins(E, cells).items():
        out[fabrics[j]] = {"verdict": m["verdict"], "rival": fabrics[m["rival"]], "margin": m["margin"], "se": m["se"],
                           "starts": m["members"], "cut": m["cut"], "cut_lost": m["cut_lost"],
                           "failed": [fabrics[i] for i in m["failed"]]}
    return out


def _tris(tr, cfg: DictConfig) -> np.ndarray:
    from vidsim.clothfit.rig import skirt_model_mesh

    sk = cfg.cloth.skirt
    return skirt_model_mesh(tr.skirt, int(sk.model_rings), int(sk.model_around), str(sk.model_rest_bend))[0].triangles


def _stills_figure(stills: list, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not stills:  # every fabric failed on its own skirt: say so in the declared figure
        fig, ax = plt.subplots(figsize=(6, 1.5))
        ax.text(0.5, 0.5, "no side-by-side: every fabric's parameters failed to simulate on its own skirt "
                "(skirt.yaml, the log)", ha="center", va="center", fontsize=8, wrap=True)
        ax.set_axis_off()
        save_figure(fig, path)
        return
    fig, axes = plt.subplots(len(stills), 3, figsize=(9, 1.7 * len(stills) + 0.4), squeeze=False)
    for row, (fab, ims) in zip(axes, stills):
        for ax, im, lab in zip(row, ims, ("first", "middle", "last")):
            ax.imshow(im)
            ax.set_axis_off()
            ax.set_title(f"{fab}: footage | model ({lab} frame)", fontsize=7)
    save_figure(fig, path)


main = stage_app("skirt_cloth", run)

if __name__ == "__main__":
    main()
