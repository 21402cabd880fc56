"""Strict JSON outputs: no NaN/Infinity tokens (Python reads them, browsers and jq refuse them).

``write_json`` writes a non-finite float as null, or where a reader computes with it again as the
string "nan"/"inf"/"-inf" that ``restore_nonfinite`` turns back; the optimisers' evaluation logs
(:class:`vidsim.optim.cache.EvalCache`) replay such values exactly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from vidsim.io.atomic import restore_nonfinite, to_json, write_json
from vidsim.optim.cache import EvalCache
from conftest import strict_loads

DOC = {"a": float("nan"), "b": [1.5, float("inf"), {"c": -np.inf}], "arr": np.array([[0.25, np.nan], [np.inf, 2.0]]),
       "n": np.float32("nan"), "i": np.int64(3), "s": "text", "ok": None}




def test_write_json_is_strict_with_null_for_nonfinite_values(tmp_path):
    write_json(tmp_path / "x.json", DOC)
    got = strict_loads((tmp_path / "x.json").read_text())
    assert got == {"a": None, "b": [1.5, None, {"c": None}], "arr": [[0.25, None], [None, 2.0]], "n": None, "i": 3,
                   "s": "text", "ok": None}


def test_string_mode_round_trips_every_value(tmp_path):
    write_json(tmp_path / "x.json", DOC, nonfinite="string")
    raw = strict_loads((tmp_path / "x.json").read_text())
    assert raw["a"] == "nan" and raw["b"][1] == "inf" and raw["b"][2]["c"] == "-inf" and raw["arr"][0][1] == "nan"
    back = restore_nonfinite(raw)
    assert math.isnan(back["a"]) and back["b"][:2] == [1.5, math.inf] and back["b"][2]["c"] == -math.inf
    assert math.isnan(back["arr"][0][1]) and back["arr"][1] == [math.inf, 2.0] and back["s"] == "text"
    with pytest.raises(ValueError, match="nonfinite"):
        to_json(DOC, nonfinite="zero")


def test_string_mode_refuses_a_string_that_would_come_back_as_a_float(tmp_path):
    """A legitimate string "nan"/"inf"/"-inf" (a label) would be read back as a float: refused by
    key path and value, and no file is written; null mode writes it as it is."""
    doc = {"cases": [{"label": "ok"}, {"label": "-inf"}]}
    with pytest.raises(ValueError, match=r"cases\[1\]\.label = '-inf'"):
        write_json(tmp_path / "x.json", doc, nonfinite="string")
    assert not (tmp_path / "x.json").exists()
    with pytest.raises(ValueError, match=r"tags\[0\] = 'nan'"):
        to_json({"tags": np.array(["nan"])}, nonfinite="string")
    assert strict_loads(to_json(doc)) == doc
    assert restore_nonfinite(strict_loads(to_json({"s": "NaN", "t": "info"}, "string"))) == {"s": "NaN", "t": "info"}


def test_eval_log_lines_are_strict_and_replay_nonfinite_info(tmp_path):
    log = tmp_path / "evals.jsonl"
    calls = []

    def fn(u):
        calls.append(u)
        return float(u.sum()), {"frames": [1.0, float("nan"), float("inf")], "note": "x"}

    with EvalCache(fn, log, context="ctx") as c:
        f0 = c(np.array([0.25, 0.5]))
        info0 = c.store[next(iter(c.store))][1]
    for line in log.read_text().splitlines():
        strict_loads(line)
    with EvalCache(fn, log, context="ctx") as c:
        assert c(np.array([0.25, 0.5])) == f0 and len(calls) == 1  # replayed, not recomputed
        info = c.store[next(iter(c.store))][1]
    assert info["frames"][0] == 1.0 and math.isnan(info["frames"][1]) and info["frames"][2] == math.inf
    assert info0["note"] == info["note"] == "x"
