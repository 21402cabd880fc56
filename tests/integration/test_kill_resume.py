"""Faults: an annealing process killed by a real SIGKILL midway resumes to the uninterrupted result."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

JOB = Path(__file__).with_name("anneal_job.py")


def _run(cache: Path, result: Path, delay: float) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(JOB.parents[2])}
    return subprocess.Popen([sys.executable, str(JOB), str(cache), str(result), str(delay)], env=env)


def _lines(p: Path) -> int:
    return p.read_bytes().count(b"\n") if p.exists() else 0


def test_sigkill_midway_then_resume_gives_the_uninterrupted_result(tmp_path):
    # reference: one uninterrupted run
    ref_res = tmp_path / "ref.json"
    assert _run(tmp_path / "ref.jsonl", ref_res, 0.0).wait(timeout=120) == 0
    ref = json.loads(ref_res.read_text())

    # the same job, slowed down, killed by a real signal once ~1/3 of its evaluations are logged
    cache, res = tmp_path / "job.jsonl", tmp_path / "job.json"
    p = _run(cache, res, 0.02)
    deadline = time.time() + 120
    while _lines(cache) < ref["n_new"] // 3 and time.time() < deadline:
        assert p.poll() is None, "the job ended before it could be killed"
        time.sleep(0.05)
    p.send_signal(signal.SIGKILL)
    assert p.wait(timeout=30) == -signal.SIGKILL
    done_before = _lines(cache)
    assert 0 < done_before < ref["n_new"], "the kill did not land midway"
    assert not res.exists(), "a killed job left a result file behind"

    # restart: same command; it replays the logged evaluations and continues
    assert _run(cache, res, 0.0).wait(timeout=120) == 0
    out = json.loads(res.read_text())
    assert out["best_u"] == ref["best_u"] and out["best_f"] == ref["best_f"]  # bit-identical
    assert out["n_evals"] == ref["n_evals"]
    # only the evaluations lost to the kill were computed again (at most the one in flight)
    assert done_before <= out["n_hits"] <= ref["n_evals"]
    assert out["n_new"] == ref["n_new"] - done_before
    assert not list(tmp_path.glob(".*.part*")), "an atomic write left a temporary file"
