"""Stage ``compare_cloth``: per-trial annealing vs joint annealing vs CMA-ES, on held-out motion.

Beyond the seed (issue 5): for each fabric of ``cloth.compare.fabrics`` three estimates, each
simulated on the fabric's *held-out* footage (the robot motion, never fitted):

* ``anneal``: the seed's procedure, annealing per trial then cross-trial selection (E1 + E2);
* ``joint``: one annealing over both trials at once (their errors summed), the seed's "more
  general solution";
* ``cmaes``: CMA-ES per trial at the same evaluation budget, then the same selection.

Inputs (Snakemake fills them, one entry per fabric in order): ``heldout`` footage folders,
``anneal``/``cmaes`` selected ``params.yaml``, ``joint`` ``fit.yaml``; and the fits' ``trace.csv``
files (``anneal_traces``/``cmaes_traces``: per fabric its trials in order; ``joint_traces``).
Writes ``compare.csv`` / ``compare.yaml`` (held-out error per fabric and method, and the budget each
used in trial simulations (:data:`SIMULATIONS_COUNTED`): true simulations only, a repeated point the
fit's cache answered not counted (``trace.csv``'s ``simulated`` column; for a trace written before
that column, the distinct points of the ``evals.jsonl`` beside it, which holds exactly the run's own
evaluations since 3 Dec 2026), a joint evaluation counted
once per trial, and for the per-trial methods the selection's simulations (every candidate on every
trial, and a polish's, from ``params.yaml``'s ``trial_simulations``) included),
``heldout.png`` and ``curves.png`` (best error so far against evaluations, annealing vs CMA-ES).

Is the best method's lead decided? Each estimate is also scored as ``cloth.compare.chaos_draws``
copies moved by ``chaos_sigma`` (the fixed draws of ``cloth.model.chaos_members``, the same for
every method); per fabric the method of least mean error over the copies is ``decided`` when its
copies beat every other method's copy by copy (:func:`vidsim.cli.cloth_common.paired_margins`,
paired t at 95 %), else the lead is within the model's chaos at these estimates. The test covers
that chaos only, not the fits' spread over annealing seeds.

Checkpoint: every held-out simulation (the estimates and their moved copies) is logged as it
finishes to ``.compare_cloth.checkpoint/fabric<i>.jsonl`` (``copies/`` for the copies) in the output
folder (:class:`vidsim.cli.cloth_common.LoggedScores`, keyed by the objective's fingerprint); a killed
run, run again, replays what was logged and writes the uninterrupted run's outputs bit for bit. The
folder is removed once ``compare.yaml`` is written.
"""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import (
    ClothStageError,
    LoggedScores,
    chaos_copies,
    load_trial,
    make_objective,
    paired_margins,
    params_from_dict,
    read_selected,
)
from vidsim.io.atomic import write_text, write_yaml
from vidsim.optim.cache import logged_keys
from vidsim.log.progress import Progress
from vidsim.report.figures import save_figure

METHODS = ("anneal", "joint", "cmaes")

#: what ``trial_simulations`` counts (written beside it in compare.yaml)
SIMULATIONS_COUNTED = ("simulations of one trial's footage each method made: its fits' distinct evaluated points (a "
                       "point the fit's cache answered again is not a simulation; a joint evaluation simulates every "
                       "trial) plus, for anneal and cmaes, the cross-trial selection's (every candidate on every "
                       "trial) and its polish's; the held-out scoring here is not counted")


def read_trace(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``(energy, best_so_far, simulated)`` columns of a fit's ``trace.csv`` (names a missing file
    or column; ``simulated`` is 1 where the evaluation simulated, 0 where the fit's cache answered,
    None in a trace written before 5 Dec 2026, which had no such column: :func:`fit_simulations`)."""
    p = Path(path)
    if not p.is_file():
        raise ClothStageError(f"{p}: trace.csv is missing")
    with p.open() as fh:
        rows = list(csv.DictReader(fh))
    if not rows or not {"energy", "best_so_far"} <= set(rows[0]):
        raise ClothStageError(f"{p}: expected columns energy and best_so_far")
    sim = np.array([int(r["simulated"]) for r in rows]) if "simulated" in rows[0] else None
    return np.array([float(r["energy"]) for r in rows]), np.array([float(r["best_so_far"]) for r in rows]), sim


def fit_simulations(trace_path: str | Path, trace: tuple) -> int | None:
    """Simulations a fit made: the sum of its trace's ``simulated`` column or, for a trace written
    before that column (5 Dec 2026), the distinct points of the ``evals.jsonl`` beside it (since
    3 Dec 2026 ``keep_only`` leaves there exactly the run's own distinct points). None when neither
    is available: no column, and no log or one holding more points than the trace has rows (records
    of other runs, a log from before ``keep_only``)."""
    if trace[2] is not None:
        return int(trace[2].sum())
    log = Path(trace_path).with_name("evals.jsonl")
    if not log.is_file():
        return None
    n = len(logged_keys(log))
    return n if 0 < n <= len(trace[0]) else None


def selection_simulations(doc: dict, where: str) -> int:
    """Trial simulations a ``select_cloth`` output made (its ``trial_simulations``; in a file
    written before they were recorded, every candidate row on every trial, when it had no polish)."""
    sims = doc.get("trial_simulations")
    if isinstance(sims, dict) and {"selection", "polish"} <= set(sims):
        return int(sims["selection"]) + int(sims["polish"])
    if doc.get("polish") is not None:
        raise ClothStageError(f"{where}: field 'trial_simulations' is missing and the selection was polished: rerun "
                              "select_cloth to count the polish's simulations")
    rows = doc.get("rows")
    if not isinstance(rows, list):
        raise ClothStageError(f"{where}: fields 'trial_simulations' and 'rows' are missing (not a select_cloth output)")
    return int(sum(len(r["errors"]) for r in rows))


def run(cfg: DictConfig) -> None:
    out = Path(cfg.paths.out)
    cc = cfg.cloth.compare
    fabrics = list(cc.fabrics)
    n = len(fabrics)
    lists = {k: list(cc[k]) for k in ("heldout", "anneal", "cmaes", "joint")}
    if not n or any(len(v) != n for v in lists.values()):
        raise ClothStageError(f"cloth.compare: fabrics ({n}) and heldout/anneal/cmaes/joint "
                              f"({', '.join(str(len(v)) for v in lists.values())}) must be lists of one length")
    nt = len(cc.anneal_traces) // n if n else 0
    if len(cc.anneal_traces) != nt * n or len(cc.cmaes_traces) != nt * n or len(cc.joint_traces) != n or nt < 1:
        raise ClothStageError("cloth.compare: anneal_traces and cmaes_traces need the same number of trials per fabric, "
                              "joint_traces one per fabric")
    draws, sigma = chaos_copies(cc, "cloth.compare")
    for p in lists["joint"]:
        if not Path(p).is_file():
            raise ClothStageError(f"{p}: fit.yaml is missing")
    docs = {m: read_selected(lists[m]) for m in METHODS}
    sets = {m: [params_from_dict(d["params"], p) for d, p in zip(docs[m], lists[m])] for m in METHODS}
    traces = {"anneal": [read_trace(p) for p in cc.anneal_traces], "cmaes": [read_trace(p) for p in cc.cmaes_traces],
              "joint": [read_trace(p) for p in cc.joint_traces]}
    # budget in true trial simulations (SIMULATIONS_COUNTED), checked before the held-out simulations
    paths = {"anneal": list(cc.anneal_traces), "cmaes": list(cc.cmaes_traces), "joint": list(cc.joint_traces)}
    sims = {m: [fit_simulations(p, t) for p, t in zip(paths[m], traces[m])] for m in METHODS}
    uncounted = [str(p) for m in METHODS for p, s_ in zip(paths[m], sims[m]) if s_ is None]
    if uncounted:
        raise ClothStageError(
            "trace.csv without the column 'simulated' (written before 5 Dec 2026, when cache answers counted as "
            "evaluations) and no evals.jsonl beside it to count the fit's distinct points from: " + ", ".join(uncounted)
            + ". Force the fits that wrote them (snakemake --forcerun fit_cloth fit_cloth_cmaes fit_cloth_joint, or "
            "only the rules of these folders); their evaluation logs' fingerprints include the source digest, so a "
            "rerun refits from scratch (minutes per fit), it does not replay")
    fits = {m: [sum(sims[m][i * nt + k] for k in range(nt)) for i in range(n)] for m in ("anneal", "cmaes")}
    fits["joint"] = [nt * s_ for s_ in sims["joint"]]
    select = {m: [selection_simulations(d, p) for d, p in zip(docs[m], lists[m])] for m in ("anneal", "cmaes")}
    select["joint"] = [0] * n
    evals = {m: [fits[m][i] + select[m][i] for i in range(n)] for m in METHODS}
    E = np.zeros((n, len(METHODS)))
    prog = Progress(E.size * (2 if draws else 1), "compare_cloth held-out", enabled=cfg.log.progress)
    ccfg = OmegaConf.merge(cfg, {"cloth": {"model": {"chaos_members": int(draws), "chaos_sigma": float(sigma)}}}) if draws else None
    copies = [[[] for _ in METHODS] for _ in range(n)]
    ckpt = out / ".compare_cloth.checkpoint"  # the held-out simulations' logs; removed once compare.yaml is written
    if ckpt.is_dir():
        print(f"compare_cloth: resuming from {ckpt} (simulations already logged are replayed)", flush=True)
    for i, f in enumerate(lists["heldout"]):
        tr = load_trial(f, cfg)
        obj = LoggedScores(make_objective([tr], cfg), ckpt / f"fabric{i}.jsonl")
        try:
            for m, meth in enumerate(METHODS):
                E[i, m] = obj.evaluate_params(sets[meth][i]).score
                prog.update(note=f"{fabrics[i]} {meth}")
        finally:
            obj.close()
        if ccfg is not None:
            cobj = LoggedScores(make_objective([tr], ccfg), ckpt / "copies" / f"fabric{i}.jsonl")
            try:
                for m, meth in enumerate(METHODS):
                    r = cobj.evaluate_params(sets[meth][i])
                    copies[i][m] = list(r.members[0]) if r.ok and r.members else []
                    prog.update(note=f"{fabrics[i]} {meth}, {int(draws)} moved copies")
            finally:
                cobj.close()
    best = [METHODS[int(np.argmin(E[i]))] for i in range(n)]
    leads = {fab: _lead(copies[i]) for i, fab in enumerate(fabrics)} if draws else {}
    _figures(fabrics, E, traces, nt, out)  # the figures first, the tables last (a kill leaves no new table beside old figures)
    write_text(out / "compare.csv", "fabric," + ",".join(f"heldout_{m}" for m in METHODS) + "," +
               ",".join(f"simulations_{m}" for m in METHODS) + ",best\n" + "".join(
                   f"{fab}," + ",".join(f"{E[i, m]:.5g}" for m in range(len(METHODS))) + "," +
                   ",".join(str(evals[m][i]) for m in METHODS) + f",{best[i]}\n" for i, fab in enumerate(fabrics)))
    write_yaml(out / "compare.yaml", {
        "fabrics": fabrics, "methods": list(METHODS), "heldout_error": E.tolist(), "trial_simulations": evals,
        "trial_simulations_counted": SIMULATIONS_COUNTED,
        "trial_simulations_parts": {m: {"fits": fits[m], "selection": select[m]} for m in METHODS},
        "best_on_heldout": dict(zip(fabrics, best)),
        "wins": {m: int(sum(b == m for b in best)) for m in METHODS},
        "copies": {"draws": int(draws), "sigma": float(sigma), "leads": leads}})
    shutil.rmtree(ckpt, ignore_errors=True)
    print("compare_cloth: best on held-out " + ", ".join(f"{f}: {b}" for f, b in zip(fabrics, best))
          + ("; over the moved copies " + ", ".join(f"{f}: {v['best']} ({'decided' if v['decided'] else 'undecided'})"
                                                    for f, v in leads.items()) if leads else ""), flush=True)


def _lead(members: list[list[float]]) -> dict:
    """The method of least mean error over the moved copies and whether its lead is decided: the
    diagonal test of :func:`~vidsim.cli.cloth_common.paired_margins` on a matrix whose columns all
    hold the methods' copies (column ``b``: does method ``b`` beat every other method?)."""
    k = len(METHODS)
    ok = all(len(x) >= 2 and len(x) == len(members[0]) and np.all(np.isfinite(x)) for x in members)
    if not ok:  # a failed copy (or none): no test
        return {"best": None, "decided": False,
                "mean_error": {m: (float(np.mean(x)) if x else None) for m, x in zip(METHODS, members)}}
    means = np.array([float(np.mean(x)) for x in members])
    b = int(np.argmin(means))
    v = paired_margins(np.tile(means[:, None], (1, k)), [[list(x)] * k for x in members])[b]
    return {"best": METHODS[b], "decided": bool(v["decided"]), "rival": METHODS[v["rival"]], "margin": v["margin"],
            "se": v["se"], "copies": v["members"], "mean_error": dict(zip(METHODS, means.tolist()))}


def _figures(fabrics: list[str], E: np.ndarray, traces: dict, nt: int, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(fabrics)
    fig, ax = plt.subplots(figsize=(1.6 * n + 2.5, 3))
    w = 0.27
    for m, meth in enumerate(METHODS):
        ax.bar(np.arange(n) + (m - 1) * w, E[:, m], w, label=meth)
    ax.set_xticks(range(n), fabrics)
    ax.set_ylabel("held-out error (robot motion)")
    ax.legend(fontsize=7)
    ax.set_title("per-trial annealing + selection vs joint annealing vs CMA-ES + selection", fontsize=8)
    save_figure(fig, out / "heldout.png")
    fig, axes = plt.subplots(1, n, figsize=(3.4 * n, 2.8), squeeze=False)
    for i, (ax, fab) in enumerate(zip(axes[0], fabrics)):
        for k in range(nt):
            for meth, ls in (("anneal", "-"), ("cmaes", "--")):
                b = traces[meth][i * nt + k][1]
                ax.plot(np.arange(1, b.size + 1), b, ls, color=f"C{k}", label=f"{meth} trial {k + 1}")
        ax.set_yscale("log")
        ax.set_xlabel("evaluation (grid included)")
        ax.set_title(fab, fontsize=8)
        ax.tick_params(labelsize=7)
        if i == 0:
            ax.set_ylabel("best error so far")
            ax.legend(fontsize=6)
    save_figure(fig, out / "curves.png")


main = stage_app("compare_cloth", run)

if __name__ == "__main__":
    main()
