"""compare_cloth's budget in trial simulations counts true simulations: a point a fit's evaluation
cache answered again is not one (trace.csv's ``simulated`` column), the cross-trial selection's
simulations (every candidate on every trial, and a polish's) are added to the per-trial methods, and
a joint evaluation counts once per trial. Before 5 Dec 2026 (session 35) it counted trace rows (cache
answers included) and left the selection out; a trace from before the column is counted from the
fit's evals.jsonl."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import yaml

import vidsim.cli.cloth_compare as stage
from vidsim.cli.cloth_common import ClothStageError
from vidsim.cli.cloth_fit import simulated_flags
from vidsim.clothfit.objective import space_from_config
from vidsim.clothfit.study import fit
from vidsim.config import CONF_DIR
from vidsim.optim.cache import EvalCache, point_key

P = {"bend": 1e-5, "stretch": 200.0, "shear": 30.0, "bend_damping": 3e-8, "stretch_damping": 3e-3,
     "shear_damping": 3e-3, "drag_linear": 0.5, "drag_quad": 0.7, "drag_degrade": 0.2, "density": 0.2}


class _Quadratic:
    """A cheap objective on two parameters (a bowl in the unit cube), counting its simulations."""

    def __init__(self):
        self.space = space_from_config({"stretch": {"lo": 10.0, "hi": 3000.0, "log": True},
                                        "drag_quad": {"lo": 0.1, "hi": 3.0, "log": True}})
        self.n = 0

    def __call__(self, u):
        self.n += 1
        return float(np.sum((np.asarray(u) - 0.3) ** 2)), {}


def test_a_fits_trace_marks_the_cache_answers():
    obj = _Quadratic()
    res = fit(obj, grid_params=["stretch"], levels=3, budget=12, seed=0)
    flags = simulated_flags(res.points)
    assert len(flags) == res.n_evals == 3 + 12
    assert sum(flags) == obj.n == len({point_key(u) for u in res.points})  # exactly the simulations made
    assert flags[3] == 0  # the annealing starts at the grid's best point: answered by the cache


def _trace(path, flags):
    e = np.linspace(5.0, 1.0, len(flags))
    path.write_text("evaluation,phase,energy,best_so_far,simulated\n" + "".join(
        f"{i},anneal,{v:.6g},{v:.6g},{s}\n" for i, (v, s) in enumerate(zip(e, flags))))


def _cfg(tmp_path, lists):
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose("config", overrides=[f"paths.results={tmp_path}", f"paths.out={tmp_path / 'compare'}",
                                            "log.rerun=false", "log.progress=false", "cloth.compare.fabrics=[twin]",
                                            *[f"cloth.compare.{k}=[{','.join(map(str, v))}]" for k, v in lists.items()]])


def test_compare_counts_true_simulations_and_the_selections(tmp_path, monkeypatch):
    monkeypatch.setattr(stage, "load_trial", lambda f, cfg: None)
    def objective(trials, cfg):  # a set's error is its stretch; its moved copies' errors spread by 1 %
        k = int(cfg.cloth.model.chaos_members)
        return SimpleNamespace(space=None, fingerprint=lambda: f"fake objective, {k} copies", evaluate_params=lambda p, keep=False: SimpleNamespace(
            score=float(p.stretch), ok=True, failure=None,
            members=[[float(p.stretch) * (1 + 0.01 * np.sin(j + 1)) for j in range(k)] if k else [float(p.stretch)]]))

    monkeypatch.setattr(stage, "make_objective", objective)
    tr = {}
    for m, flags in (("a1", [1, 1, 1, 0, 1, 1]), ("a2", [1, 1, 1, 0, 1, 0]), ("c1", [1] * 6), ("c2", [1, 1, 1, 1, 1, 0]),
                     ("j", [1, 1, 1, 0, 1, 1])):
        tr[m] = tmp_path / f"{m}.csv"
        _trace(tr[m], flags)
    rows = [{"candidate": f"t#{k}", "errors": {"exp1": 1.0, "exp2": 2.0}} for k in range(4)]
    (tmp_path / "anneal.yaml").write_text(yaml.safe_dump({"params": P, "rows": rows,
                                                          "trial_simulations": {"selection": 8, "polish": 14}}))
    (tmp_path / "cmaes.yaml").write_text(yaml.safe_dump({"params": {**P, "stretch": 150.0}, "rows": rows}))  # older file
    (tmp_path / "joint.yaml").write_text(yaml.safe_dump({"params": {**P, "stretch": 100.0}}))
    lists = {"heldout": [tmp_path / "robot"], "anneal": [tmp_path / "anneal.yaml"], "cmaes": [tmp_path / "cmaes.yaml"],
             "joint": [tmp_path / "joint.yaml"], "anneal_traces": [tr["a1"], tr["a2"]],
             "cmaes_traces": [tr["c1"], tr["c2"]], "joint_traces": [tr["j"]]}
    stage.run(_cfg(tmp_path, lists))
    doc = yaml.safe_load((tmp_path / "compare" / "compare.yaml").read_text())
    # anneal: 5 + 4 simulated trace rows, 8 selection and 14 polish simulations; cmaes: 6 + 5 and the
    # 4 candidates x 2 trials of an older params.yaml (no polish); joint: 5 points x 2 trials
    assert doc["trial_simulations"] == {"anneal": [31], "joint": [10], "cmaes": [19]}
    assert doc["trial_simulations_parts"]["anneal"] == {"fits": [9], "selection": [22]}
    assert "cache" in doc["trial_simulations_counted"] and "selection" in doc["trial_simulations_counted"]
    csv_row = (tmp_path / "compare" / "compare.csv").read_text().splitlines()[1].split(",")
    assert csv_row[4:7] == ["31", "10", "19"] and csv_row[-1] == "joint"
    # joint's estimate (stretch 100) beats cmaes' (150) and anneal's (200) in each of the 8 moved copies
    lead = doc["copies"]["leads"]["twin"]
    assert doc["copies"]["draws"] == 8 and lead["best"] == "joint" and lead["decided"] and lead["rival"] == "cmaes"
    assert lead["margin"] == pytest.approx(lead["mean_error"]["joint"] - lead["mean_error"]["cmaes"], rel=1e-12)
    # traces from before the column: counted from the evals.jsonl beside them (the run's distinct
    # points: 4 here, one failed and one answered twice), refused by name only where there is none
    old = {}
    for k in ("joint", "c2", "a1"):
        old[k] = tmp_path / f"old_{k}" / "trace.csv"
        old[k].parent.mkdir()
        old[k].write_text("evaluation,phase,energy,best_so_far\n" + "".join(f"{i},grid,1,1\n" for i in range(6)))
    with EvalCache(lambda u: float(u[0]) if u[0] < 0.7 else float("nan"), old["joint"].parent / "evals.jsonl",
                   context="c") as f:
        for x in (0.1, 0.2, 0.2, 0.8, 0.3, 0.1):
            f(np.array([x, 0.5]))
    old_lists = {**lists, "joint_traces": [old["joint"]]}
    stage.run(_cfg(tmp_path, old_lists))
    doc = yaml.safe_load((tmp_path / "compare" / "compare.yaml").read_text())
    assert doc["trial_simulations_parts"]["joint"] == {"fits": [2 * 4], "selection": [0]}
    with pytest.raises(ClothStageError) as err:
        stage.run(_cfg(tmp_path, {**old_lists, "cmaes_traces": [tr["c1"], old["c2"]], "anneal_traces": [old["a1"], tr["a2"]]}))
    msg = str(err.value)
    assert str(old["c2"]) in msg and str(old["a1"]) in msg and str(old["joint"]) not in msg  # every one at once
    assert "fit_cloth fit_cloth_cmaes fit_cloth_joint" in msg and "refits from scratch" in msg
    # a log holding more points than the trace has rows (other runs' records) is not trusted
    with EvalCache(lambda u: 1.0, old["c2"].parent / "evals.jsonl", context="c") as f:
        for x in range(7):
            f(np.array([x / 10, 0.5]))
    with pytest.raises(ClothStageError, match="old_c2/trace.csv"):
        stage.run(_cfg(tmp_path, {**lists, "cmaes_traces": [tr["c1"], old["c2"]]}))
    # a polished selection that did not record its simulations
    (tmp_path / "cmaes.yaml").write_text(yaml.safe_dump({"params": P, "rows": rows, "polish": {"budget": 6}}))
    with pytest.raises(ClothStageError, match="cmaes.yaml: field 'trial_simulations' is missing"):
        stage.run(_cfg(tmp_path, lists))


def test_a_lead_within_the_copies_spread_is_undecided():
    """``_lead`` (compare_cloth): the best method over the moved copies is decided only when it beats
    every other method copy by copy beyond the paired t cut-off; overlapping copies, or a failed
    copy, leave it undecided."""
    clear = stage._lead([[10.0, 10.1, 9.9, 10.05], [12.0, 12.1, 11.9, 12.0], [15.0, 15.2, 14.9, 15.1]])
    assert clear["best"] == "anneal" and clear["decided"] and clear["rival"] == "joint"
    mixed = stage._lead([[10.0, 14.0, 9.0, 13.0], [11.0, 10.0, 12.0, 12.0], [20.0, 21.0, 19.0, 20.0]])
    assert mixed["best"] == "joint" and not mixed["decided"]  # means 11.5 vs 11.25, copies cross
    # beats one method clearly but not the other: undecided (the lead must hold against every method)
    half = stage._lead([[10.0, 10.1, 9.9, 10.0], [10.5, 9.0, 11.0, 10.2], [15.0, 15.1, 14.9, 15.0]])
    assert half["best"] == "anneal" and not half["decided"]
    failed = stage._lead([[10.0, 10.1], [], [15.0, 15.1]])
    assert failed["best"] is None and not failed["decided"] and failed["mean_error"]["joint"] is None
