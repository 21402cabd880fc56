"""Rerun recording ids: two outputs opened together stay apart (review, 5 Dec 2026: the annealing
and CMA-ES fits of one trial shared an id and merged in the viewer, and staging folders leaked
their temporary names into the id)."""

from __future__ import annotations

from vidsim.log import RerunLogger


def _rid(path) -> str:
    lg = RerunLogger(path, "vidsim.test")
    try:
        return lg.rec.get_recording_id() if hasattr(lg.rec, "get_recording_id") else str(lg.rec)
    finally:
        lg.close()


def test_ids_name_the_output_folder_its_parent_and_the_file(tmp_path):
    a = _rid(tmp_path / "cloth" / "fit" / "satin_exp1" / "cloth.rrd")
    b = _rid(tmp_path / "cloth" / "fit_cmaes" / "satin_exp1" / "cloth.rrd")
    assert a == "fit/satin_exp1/cloth" and b == "fit_cmaes/satin_exp1/cloth"
    # a stage writing into its staging folder gets the final folder's name
    assert _rid(tmp_path / "edit" / ".flame_spread.part" / "fluid.rrd") == "edit/flame_spread/fluid"
