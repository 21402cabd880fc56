"""The candidates a fit hands to the cross-trial selection: best first, distinct, failures excluded."""

from __future__ import annotations

import json

import numpy as np

from vidsim.cli.cloth_fit import candidates
from vidsim.optim import FAILED_SCORE
from vidsim.optim.space import Space


def test_candidates_are_best_distinct_and_never_failures(tmp_path):
    space = Space.from_config({"stretch": {"lo": 20.0, "hi": 4000.0, "log": True}, "bend": {"lo": 1e-7, "hi": 1e-4, "log": True}})
    recs = [([0.5, 0.5], 3.0), ([0.51, 0.5], 2.5), ([0.9, 0.1], 4.0), ([0.2, 0.2], FAILED_SCORE), ([0.1, 0.9], 5.0)]
    log = tmp_path / "evals.jsonl"
    log.write_text("".join(json.dumps({"key": str(i), "u": u, "f": f, "info": {}}) + "\n" for i, (u, f) in enumerate(recs))
                   + '{"key": "torn", "u": [0.3')
    c = candidates(log, space, 3)
    assert [x["score"] for x in c] == [2.5, 4.0, 5.0]  # 3.0 is within 0.05 of the best point
    assert np.isclose(c[0]["theta"]["stretch"], space.from_unit(np.array([0.51, 0.5]))[0])
