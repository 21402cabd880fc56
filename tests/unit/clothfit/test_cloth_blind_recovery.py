"""Blind recovery of five cloth parameters from filmed footage, against a known answer.

The other cloth tests that check recovery fix the parameters they do not estimate at the truth's
values (``cloth.fit.fixed``: a one-parameter recoverability check). Here nothing is taken from the
truth: a twin (the project's simulator at a stiff bend, 8e-5 N m, where the model is not chaotic
over the clip: docs/gap.md, "A stiff twin") is filmed with stripes, segmented and turned into angle
maps; the fit (a 4-level grid over bend, stretch and shear, then 150 annealing evaluations) reads
only that footage side (``ClothCase.fit_trial``) and estimates bend, stretch, shear and both drags.
The four parameters it does not estimate are the model's own defaults, which the twin shares (a
known-input assumption, stated in vidsim/gap/cloth_suite.py). The grid's levels do not contain the
true values. Measured (6 Dec 2026): bend +0.3 %, stretch +17 %, shear -13 %, linear drag +9 %,
quadratic drag -15 %; 22 CPU-s to film, 32 to fit.
"""

from __future__ import annotations

import pytest

from vidsim.gap.cloth_suite import ClothSceneConfig, fit_case, make_case

TRUE = {"bend": 8e-5, "stretch": 300.0, "shear": 40.0, "drag_linear": 0.4, "drag_quad": 0.8}


@pytest.mark.slow
def test_five_parameters_recovered_from_footage_blind():
    scene = ClothSceneConfig(twin_params=dict(TRUE), budget=150, grid_levels=4, settle_s_model=1.0)
    cc = make_case({"label": "none", "seed": 320}, scene)
    fitted, info = fit_case(cc.fit_trial, scene)
    truth = cc.truth["params"]
    assert {k: truth[k] for k in TRUE} == TRUE  # the twin was filmed with these
    err = {k: getattr(fitted, k) / truth[k] - 1.0 for k in scene.estimate}
    assert abs(err["bend"]) < 0.05, err
    for k in ("stretch", "shear", "drag_linear", "drag_quad"):
        assert abs(err[k]) < 0.25, (k, err)
    assert info["n_evals"] > 4 ** 3  # the annealing ran past the grid
