"""gap_suite checkpoint: a case that finished before a crash is kept, the rest run, a changed key reruns.

``run_case`` (film, fit, diagnose: minutes per case) is replaced by a recorder so that the test
checks the stage's bookkeeping only; the real cases run in the suite's own tests and stage.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import vidsim.cli.gap_suite as stage
import vidsim.gap.suite as suite
from vidsim.config import CONF_DIR


class _Diag:
    def __init__(self, name: str):
        self.name = name

    def to_dict(self) -> dict:
        return {"fake": self.name}


def _score(label: str) -> dict:
    return {"label": label, "named": [], "named_first": "none", "correct": label == "none", "gap_present": False,
            "heldout_before_px": 1.0, "noise_floor_px": 0.9, "closure": {}, "recovery": {}}


def _cfg(out: Path, *extra: str):
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose("config", overrides=[f"paths.results={out.parent}", f"paths.out={out}", "log.rerun=false",
                                            "log.progress=false", "gap.only=[null_a,null_b,lens_k1]", *extra])


@pytest.fixture
def calls(monkeypatch):
    made: list[int] = []
    crash_at: dict[str, int | None] = {"seed": None}

    def fake_run_case(case, dcfg, scene, checkpoint=None):
        Path(checkpoint).mkdir(parents=True, exist_ok=True)  # a finished step of the case's diagnosis
        (Path(checkpoint) / "base-0.pkl").write_bytes(b"step")
        if case["seed"] == crash_at["seed"]:
            raise RuntimeError("killed mid-suite")
        made.append(case["seed"])
        return _Diag(str(case["seed"])), _score(case["label"]), None, None

    monkeypatch.setattr(suite, "run_case", fake_run_case)
    monkeypatch.setattr(stage, "plot_diagnosis", lambda d, path, title="": Path(path).write_bytes(b"png"))
    monkeypatch.setattr(stage, "log_diagnosis", lambda lg, d, masks, prefix="": None)
    return made, crash_at


def test_resume_keeps_finished_cases_and_reruns_on_a_changed_key(tmp_path, calls):
    made, crash_at = calls
    out = tmp_path / "suite"
    crash_at["seed"] = 203  # lens_k1, the third case
    with pytest.raises(RuntimeError):
        stage.run(_cfg(out))
    assert made == [201, 202] and not out.exists()
    assert sorted(p.name for p in (tmp_path / ".suite.part" / "cases").iterdir()) == [
        "null_a.json", "null_a.png", "null_a.rrd", "null_b.json", "null_b.png", "null_b.rrd"]
    # the killed case's finished diagnosis steps are kept for the rerun; the finished cases' are gone
    assert [p.name for p in (tmp_path / ".suite.part" / "steps").iterdir()] == ["lens_k1"]

    crash_at["seed"] = None
    stage.run(_cfg(out))
    assert made == [201, 202, 203]  # only the unfinished case ran
    assert not (out / "steps").exists()
    summ = json.loads((out / "suite.json").read_text())
    assert summ["resumed_cases"] == ["null_a", "null_b"]
    assert summ["headline"]["null_cases_naming_nothing"] == "2/2"
    assert not (tmp_path / ".suite.part").exists()

    # a crash after a changed diagnosis setting: the stored cases do not match and are recomputed
    crash_at["seed"] = 203
    with pytest.raises(RuntimeError):
        stage.run(_cfg(out, "gap.diagnose.top_k=2"))
    crash_at["seed"] = None
    assert made == [201, 202, 203, 201, 202]  # the finished output's cases (top_k=3) did not match
    stage.run(_cfg(out, "gap.diagnose.top_k=3", "gap.only=[null_a,lens_k1]"))
    # top_k=3 is the default: the staged null_a (written with top_k=2) is stale, but the finished
    # output's null_a and lens_k1 match, so they are copied in and nothing runs
    assert made == [201, 202, 203, 201, 202]
    summ = json.loads((out / "suite.json").read_text())
    assert summ["resumed_cases"] == ["null_a", "lens_k1"] and sorted(summ["cases"]) == ["lens_k1", "null_a"]
    assert sorted(p.name for p in (out / "cases").iterdir()) == ["lens_k1.json", "lens_k1.png", "lens_k1.rrd",
                                                                 "null_a.json", "null_a.png", "null_a.rrd"]


def test_resumed_suite_recording_holds_every_case(tmp_path, calls, monkeypatch):
    """suite.rrd after a resume: the cases finished before the kill are in it, not only those after."""
    import subprocess
    import sys

    made, crash_at = calls
    monkeypatch.setattr(stage, "log_diagnosis",
                        lambda lg, d, masks, prefix="": lg.scalar(f"{prefix}metric/gap_base_px", 1.0))
    out = tmp_path / "suite"
    crash_at["seed"] = 203
    with pytest.raises(RuntimeError):
        stage.run(_cfg(out, "log.rerun=true"))
    crash_at["seed"] = None
    stage.run(_cfg(out, "log.rerun=true"))
    assert made == [201, 202, 203]
    r = subprocess.run([sys.executable, "-m", "rerun", "rrd", "print", str(out / "suite.rrd")],
                       capture_output=True, text=True, check=True)
    for case in ("null_a", "null_b", "lens_k1"):
        assert f"/{case}/metric/gap_base_px" in r.stdout
    assert r.stdout.count("StoreInfo") == 1  # one recording, not three


def test_cases_run_without_recording_are_rerun_once_recording_is_on(tmp_path, calls):
    """A case finished with log.rerun=false holds a placeholder recording: not reused when it is on."""
    made, _ = calls
    out = tmp_path / "suite"
    stage.run(_cfg(out))  # log.rerun=false
    assert made == [201, 202, 203]
    stage.run(_cfg(out, "log.rerun=true"))
    assert made == [201, 202, 203] * 2
    stage.run(_cfg(out, "log.rerun=true"))  # now with recordings: kept
    assert made == [201, 202, 203] * 2


def test_cloth_suite_resumes_the_same_way(tmp_path, monkeypatch):
    """gap_cloth_suite keeps finished cases (no figure per case there) and writes shrinkage.csv."""
    import vidsim.cli.gap_cloth_suite as cstage
    import vidsim.gap.cloth_suite as csuite
    from hydra import compose, initialize_config_dir

    made: list[int] = []
    crash = {"seed": 305}

    def fake_run_case(case, scene, dcfg, cloth_cfg=None, progress=None, checkpoint=None):
        if case["seed"] == crash["seed"]:
            raise RuntimeError("killed mid-suite")
        made.append(case["seed"])
        s = _score(case["label"])
        s.update({"effect_footprint_px": None, "noise_footprint_px": 12.5})
        return _Diag(str(case["seed"])), s, None

    monkeypatch.setattr(csuite, "run_case", fake_run_case)
    out = tmp_path / "cloth"

    def cfg(*extra):
        with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
            return compose("config", overrides=[f"paths.results={tmp_path}", f"paths.out={out}", "log.rerun=false",
                                                "log.progress=false", "gap.cloth.only=[null_a,wind,lens_k1]", *extra])

    with pytest.raises(RuntimeError):
        cstage.run(cfg())
    assert made == [320, 302] and not out.exists()
    crash["seed"] = None
    cstage.run(cfg())
    assert made == [320, 302, 305]
    summ = json.loads((out / "suite.json").read_text())
    assert summ["resumed_cases"] == ["null_a", "wind"]
    # one case added to the finished suite: only that case runs
    cstage.run(cfg("gap.cloth.only=[null_a,wind,lens_k1,time_offset]"))
    assert made == [320, 302, 305, 304]
    made.pop()
    cstage.run(cfg())  # and back: the three are kept, time_offset leaves the output
    assert made == [320, 302, 305] and not (out / "cases" / "time_offset.json").exists()
    rows = (out / "shrinkage.csv").read_text().splitlines()
    assert rows[0].endswith("effect_footprint_px,noise_footprint_px") and len(rows) == 4
    assert rows[1].startswith("null_a,none,none,True") and rows[1].endswith(",12.50")
    # a crash after a changed setting: the stored cases do not match and are recomputed
    stored = json.loads((out / "cases" / "null_a.json").read_text())
    assert stored["key"]["case"]["seed"] == 320 and "cloth" in stored["key"]
    crash["seed"] = 305
    with pytest.raises(RuntimeError):
        cstage.run(cfg("+gap.cloth.scene.budget=31"))
    assert made == [320, 302, 305, 320, 302]
    crash["seed"] = None
    cstage.run(cfg("cloth.fit.alpha=0.2", "+gap.cloth.scene.budget=31"))  # the cloth node is in the key too
    assert made == [320, 302, 305, 320, 302, 320, 302, 305]
    assert json.loads((out / "suite.json").read_text())["resumed_cases"] == []


def test_a_case_failing_at_run_time_is_a_failed_score_not_the_end_of_the_suite(tmp_path, monkeypatch, calls):
    """A diverged single-start fit raised GapError, which the stage turned into a configuration error:
    every rerun died at the same case and suite.json never came (resume audit, 5 Dec 2026)."""
    made, _ = calls

    def failing(case, dcfg, scene, checkpoint=None):
        if case["seed"] == 201:
            raise suite.CaseFailed("the single-start fit diverged")
        made.append(case["seed"])
        return _Diag(str(case["seed"])), _score(case["label"]), None, None

    monkeypatch.setattr(suite, "run_case", failing)
    out = tmp_path / "suite"
    stage.run(_cfg(out))
    summ = json.loads((out / "suite.json").read_text())
    assert made == [202, 203]
    a = summ["cases"]["null_a"]
    assert a["correct"] is False and "diverged" in a["failed"] and a["named_first"] == "(failed)"
    assert summ["headline"]["null_cases_naming_nothing"] == "1/2"  # a failed null case has not named nothing
    assert "null_a,none,failed,False,,," in (out / "shrinkage.csv").read_text()
    assert (out / "cases" / "null_a.png").stat().st_size > 0


def test_a_code_change_reruns_the_cases(tmp_path, monkeypatch, calls):
    """The cases' keys carry the package's source digest: after a code change (and --forcerun) the
    finished output's cases were copied back with their old figures."""
    import vidsim

    made, _ = calls
    out = tmp_path / "suite"
    stage.run(_cfg(out))
    assert made == [201, 202, 203]
    monkeypatch.setattr(vidsim, "SOURCE_DIGEST", "another-version")
    stage.run(_cfg(out))
    assert made == [201, 202, 203, 201, 202, 203]


def test_a_resumed_case_with_nonfinite_figures_scores_as_an_uninterrupted_run(tmp_path, monkeypatch):
    """The case files are strict JSON (non-finite numbers as the strings "nan"/"inf"/"-inf", not NaN
    tokens); a resumed suite reads them back as floats, so its headline, shrinkage.csv and suite.json
    equal an uninterrupted run's (a null read back as "not measured" would have changed the headline)."""
    from conftest import strict_loads

    crash = {"seed": None}

    def fake_run_case(case, dcfg, scene, checkpoint=None):
        if case["seed"] == crash["seed"]:
            raise RuntimeError("killed mid-suite")
        s = _score(case["label"])
        if case["label"] == "lens_k1":  # figures that could not be measured: NaN and infinities
            s.update({"named": ["lens_k1"], "named_first": "lens_k1", "correct": True, "noise_floor_px": float("nan"),
                      "closure": {"lens_k1": float("nan")}, "heldout_after_px": {"lens_k1": float("-inf")},
                      "recovery": {"lens_k1": {"estimate": 0.1, "truth": 0.3, "rel_error": float("inf")}}})
        return _Diag(str(case["seed"])), s, None, None

    monkeypatch.setattr(suite, "run_case", fake_run_case)
    monkeypatch.setattr(stage, "plot_diagnosis", lambda d, path, title="": Path(path).write_bytes(b"png"))
    monkeypatch.setattr(stage, "log_diagnosis", lambda lg, d, masks, prefix="": None)
    only = "gap.only=[lens_k1,null_a]"
    whole = tmp_path / "whole"
    stage.run(_cfg(whole, only))
    resumed = tmp_path / "resumed"
    crash["seed"] = 201  # null_a: lens_k1 finished before the kill
    with pytest.raises(RuntimeError):
        stage.run(_cfg(resumed, only))
    crash["seed"] = None
    stage.run(_cfg(resumed, only))
    for out in (whole, resumed):
        for f in ("suite.json", "cases/lens_k1.json", "cases/null_a.json"):
            strict_loads((out / f).read_text())  # no NaN / Infinity tokens
    raw = json.loads((resumed / "cases" / "lens_k1.json").read_text())["score"]
    assert raw["closure"] == {"lens_k1": "nan"} and raw["recovery"]["lens_k1"]["rel_error"] == "inf"
    a, b = (json.loads((o / "suite.json").read_text()) for o in (whole, resumed))
    assert b["resumed_cases"] == ["lens_k1"] and a["resumed_cases"] == []
    for d in (a, b):
        d.pop("seconds"), d.pop("resumed_cases")
    assert a == b
    # the NaN closure counts as measured and not closing, as in a run that never stopped
    assert b["headline"]["closure_not_measured"] == 0 and b["headline"]["closure_at_least_50pct"] == "0/1"
    for f in ("shrinkage.csv", "confusion.csv"):
        assert (whole / f).read_text() == (resumed / f).read_text()
    assert "lens_k1,lens_k1,lens_k1,True,1.00,nan,lens_k1,-inf,nan,0.1,0.3,inf" in (resumed / "shrinkage.csv").read_text()
