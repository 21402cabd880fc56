"""Evaluation logs belong to one objective: a rerun after the inputs changed does not replay them.

Seen on 3 Dec 2026: a twin re-filmed at another mesh resolution was refitted by Snakemake, and the
fit replayed all 164 scores of the old footage from ``evals.jsonl`` (not a declared output, so
Snakemake kept it), reporting the old optimum.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import pytest

from vidsim.optim.cache import EvalCache, fingerprint, log_context


def _calls():
    n = {"k": 0}

    def f(u):
        n["k"] += 1
        return float(np.sum(np.asarray(u) ** 2))

    return f, n


def test_same_context_replays_other_context_is_moved_aside(tmp_path) -> None:
    log = tmp_path / "evals.jsonl"
    f, n = _calls()
    pts = [np.array([0.1, 0.2]), np.array([0.3, 0.4])]
    with EvalCache(f, log, context="A") as c:
        for u in pts:
            c(u)
    assert n["k"] == 2 and log_context(log) == "A"
    with EvalCache(f, log, context="A") as c:
        vals = [c(u) for u in pts]
    assert n["k"] == 2 and c.n_hits == 2 and vals == [pytest.approx(0.05), pytest.approx(0.25)]
    with EvalCache(f, log, context="B") as c:
        c(pts[0])
    assert n["k"] == 3  # evaluated again, not replayed
    assert c.stale_moved == tmp_path / "evals.stale-1.jsonl" and c.stale_moved.is_file()
    assert log_context(log) == "B" and log_context(c.stale_moved) == "A"
    # the old records were kept, not lost
    assert sum(1 for line in c.stale_moved.read_text().splitlines() if "key" in json.loads(line)) == 2
    # a second change keeps both old logs
    with EvalCache(f, log, context="C") as c:
        pass
    assert c.stale_moved == tmp_path / "evals.stale-2.jsonl"


def test_log_without_header_is_not_replayed_under_a_context_but_is_without(tmp_path) -> None:
    log = tmp_path / "evals.jsonl"
    f, n = _calls()
    with EvalCache(f, log) as c:  # no context: no header (the logs before this change)
        c(np.array([0.5]))
    assert log_context(log) is None
    with EvalCache(f, log) as c:
        c(np.array([0.5]))
    assert n["k"] == 1  # replayed
    with EvalCache(f, log, context="A") as c:
        c(np.array([0.5]))
    assert n["k"] == 2 and c.stale_moved is not None
    with EvalCache(f, log) as c:  # no context asked: a header is skipped, the records replayed
        c(np.array([0.5]))
    assert n["k"] == 2


@dataclass
class _Settings:
    resolution: int
    settle_s: float


def test_fingerprint_sees_every_bit_and_ignores_key_order() -> None:
    a = np.linspace(0.0, 1.0, 11)
    b = a.copy()
    b[3] = np.nextafter(b[3], 2.0)  # one ulp
    assert fingerprint(a) != fingerprint(b)
    assert fingerprint(a) == fingerprint(a.copy())
    assert fingerprint(a) != fingerprint(a.astype(np.float32))
    assert fingerprint({"x": 1.0, "y": a}) == fingerprint({"y": a.copy(), "x": 1.0})
    assert fingerprint(0.1) != fingerprint(np.nextafter(0.1, 1.0))
    assert fingerprint(_Settings(12, 0.5)) != fingerprint(_Settings(12, 0.6))
    assert fingerprint(_Settings(12, 0.5)) == fingerprint(_Settings(12, 0.5))
    with pytest.raises(TypeError):
        fingerprint({1, 2})
    # strings cannot mimic the separators: before the length prefix these two hashed the same
    assert fingerprint(["a;str:b"]) != fingerprint(["a", "b"])


def test_keep_only_leaves_the_runs_own_records_and_moves_the_rest(tmp_path) -> None:
    from vidsim.optim.cache import keep_only, point_key

    log = tmp_path / "evals.jsonl"
    f, n = _calls()
    a, b, c = np.array([0.1]), np.array([0.2]), np.array([0.3])
    with EvalCache(f, log, context="A") as cache:  # an earlier run evaluated a and b
        cache(a)
        cache(b)
    with EvalCache(f, log, context="A") as cache:  # this run: b (replayed) and c
        cache(b)
        cache(c)
    assert n["k"] == 3
    aside = keep_only(log, {point_key(u) for u in (b, c)})
    assert aside == tmp_path / "evals.other-runs-1.jsonl"
    kept = [json.loads(line) for line in log.read_text().splitlines()]
    assert kept[0] == {"context": "A"} and [r["key"] for r in kept[1:]] == [point_key(b), point_key(c)]
    moved = [json.loads(line) for line in aside.read_text().splitlines()]
    assert moved[0] == {"context": "A"} and [r["key"] for r in moved[1:]] == [point_key(a)]  # only the other run's
    assert keep_only(log, {point_key(u) for u in (b, c)}) is None  # nothing more to move
    with EvalCache(f, log, context="A") as cache:  # still resumable
        cache(c)
    assert n["k"] == 3


def test_evaluate_runs_once_and_reads_the_stored_result_back(tmp_path) -> None:
    """EvalCache.evaluate: the (f, info) a caller needs when its result lives in info, replayed on
    a rerun; a floating-point error gives the failed score and an info without the result (only its reason)."""
    from vidsim.optim import FAILED_SCORE
    from vidsim.optim.cache import logged_keys

    log = tmp_path / "evals.jsonl"
    calls = []

    def run(u):
        calls.append(u)
        return 2.0, {"p": [float(u[0]), float("nan")]}

    with EvalCache(lambda u: None, log, context="A") as cache:
        f, info = cache.evaluate(np.array([0.5]), run)
    with EvalCache(lambda u: 9.0, log, context="A") as cache:
        f2, info2 = cache.evaluate(np.array([0.5]))
    assert f == f2 == 2.0 and len(calls) == 1 and info2["p"][0] == 0.5 and np.isnan(info2["p"][1])

    def boom(u):
        raise FloatingPointError

    with EvalCache(boom, None) as cache:
        f, info = cache.evaluate(np.array([0.1]))
    assert f == FAILED_SCORE and "p" not in info and info["failure"].startswith("FloatingPointError")
    assert len(logged_keys(log)) == 1
