"""The fluid family's metrics table: measured figures of the stages against the issue's targets.

Pure function of the stages' ``summary.json`` contents (dicts); the ``fluid_metrics`` stage
reads and writes the files.
"""

from __future__ import annotations

import math
from typing import Any

from vidsim.fluid.metrics import DETAIL_RATIO_MIN, EPE_REL_MAX, MIN_STATIC_PX, PATCH_RATIO_MAX

COLUMNS = ("item", "quantity", "value", "target", "met")


def _row(item: str, q: str, v: float, target: str, met: bool | None) -> dict[str, Any]:
    return {"item": item, "quantity": q, "value": v, "target": target,
            "met": "" if met is None else ("yes" if met else "NO")}


def metrics_rows(summaries: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per measured figure.

    Args:
        summaries: contents of ``fluid_middlebury``, ``fluid_flow`` and ``fluid_edit`` summaries
            (recognised by their keys).

    Returns:
        rows with keys :data:`COLUMNS`; ``met`` is ``yes``/``NO`` where the issue states a
        target, empty otherwise. Unknown summaries raise ``ValueError`` naming their keys.
    """
    rows: list[dict[str, Any]] = []
    for s in summaries:
        # a figure that could not be measured is null in a summary (strict JSON) and NaN here
        s = {k: (float("nan") if v is None else v) for k, v in s.items()}
        if "epe_px" in s and isinstance(s["epe_px"], dict):  # Middlebury
            m = s["method"]
            for scene, d in s["epe_px"].items():
                d = {k: (float("nan") if v is None else v) for k, v in d.items()}  # null: not measurable
                ref = d.get("dis_medium")
                rows.append(_row(f"middlebury/{scene}", f"epe_px ({m})", d[m],
                                 f"<= DIS medium ({ref:.4f})" if ref is not None else "", d[m] <= ref if ref is not None else None))
        elif "n_pairs" in s:  # optical flow of a footage folder
            item = f"flow/{s['footage']}"
            if "epe_px" in s:
                rows.append(_row(item, f"epe_px ({s['method']}) vs true velocity", s["epe_px"],
                                 f"<= {s['baseline']} ({s['epe_px_baseline']:.4f})", s["epe_px"] <= s["epe_px_baseline"]))
                if "epe_px_visible_fluid" in s:
                    rows.append(_row(item, "epe_px where fluid is visible", s["epe_px_visible_fluid"], "", None))
                rows.append(_row(item, "mean true speed px/frame", s["mean_speed_true_px"], "", None))
            else:
                rows.append(_row(item, f"mean estimated speed px/frame ({s['method']}, no truth: real recording)",
                                 s["mean_speed_px"], "", None))
        elif "fraction_in_desired_sink" in s:  # an edit
            item = f"edit/{s['edit']}"
            rows.append(_row(item, "fraction of source particles whose streamline ends in the desired sink",
                             s["fraction_in_desired_sink"], ">= 0.98", s["fraction_in_desired_sink"] >= 0.98))
            rows.append(_row(item, "the same at initialisation, before optimising", s["fraction_in_desired_sink_init"], "",
                             None))
            if "arrival_frames_median" in s:
                rows.append(_row(item, "median frames for a particle to reach its sink along the field",
                                 s["arrival_frames_median"], "", None))
                rows.append(_row(item, f"fraction of particles reaching their sink within the {s['frames']} rendered frames",
                                 s["fraction_arriving_within_render"], "", None))
            epe = s["rendered_flow_epe_px"]
            if "rendered_flow_epe_rel" in s:
                # relative to what a frozen render scores (the field's mean speed on the same pixels)
                rel, sp = s["rendered_flow_epe_rel"], s["edited_speed_epe_mask_px"]
                rows.append(_row(item, "rendered-flow EPE vs edited field px/frame", epe,
                                 f"<= {EPE_REL_MAX} x the field's mean speed there ({EPE_REL_MAX * sp:.4f}; a frozen "
                                 "render scores 1 x)", None if math.isnan(rel) else rel <= EPE_REL_MAX))
                rows.append(_row(item, "rendered-flow EPE / edited field's mean speed on the same pixels", rel,
                                 f"<= {EPE_REL_MAX}", None if math.isnan(rel) else rel <= EPE_REL_MAX))
            else:  # a summary written before the relative target: the figure without a verdict
                rows.append(_row(item, "rendered-flow EPE vs edited field px/frame", epe,
                                 "relative target needs rendered_flow_epe_rel (rerun the edit)", None))
            rows.append(_row(item, "edited field mean speed px/frame, whole frame", s["edited_speed_mean_px"], "", None))
            pr = s["patch_distance_ratio"]
            if "patch_coherence_ratio" in s:
                q = (f"patch-distance ratio (max of coherence {s['patch_coherence_ratio']:.3f} and "
                     f"completeness {s['patch_completeness_ratio']:.3f})")
            else:
                q = "patch-distance ratio"
            rows.append(_row(item, q, pr, f"<= {PATCH_RATIO_MAX}", None if math.isnan(pr) else pr <= PATCH_RATIO_MAX))
            if "detail_ratio" in s:
                dr = s["detail_ratio"]
                rows.append(_row(item, "detail-contrast ratio output/source (wash-out < 1)", dr, f">= {DETAIL_RATIO_MIN}",
                                 None if math.isnan(dr) else dr >= DETAIL_RATIO_MIN))
            if "footage_obstacle_grey_output" in s and not math.isnan(s["footage_obstacle_grey_source"]):
                # no verdict: the fill is the source's temporal median at full opacity, so output and
                # source agree by construction however the obstacle was declared (as static flicker)
                go, gs = s["footage_obstacle_grey_output"], s["footage_obstacle_grey_source"]
                rows.append(_row(item, f"mean grey level inside the obstacles in the footage, output (source {gs:.2f})",
                                 go, "n/a (by construction: the footage's temporal median is drawn there)", None))
            fo, fs = s["flicker_output"], s["flicker_source"]
            ok = None if (math.isnan(fo) or math.isnan(fs)) else fo <= fs
            if math.isnan(fs) or math.isnan(fo):
                target = (f"no region of >= {MIN_STATIC_PX} px static in both output and source (declared obstacles "
                          "excluded): not measurable")
            else:
                target = f"<= source ({fs:.3f}) on the same pixels"
            rows.append(_row(item, "flicker in static regions, output (grey levels; pixels static in the edited field and "
                             "the source, declared obstacles excluded)", fo, target, ok))
            if "flicker_mc_output" in s:
                rows.append(_row(item, "motion-compensated flicker, whole frame, output (grey levels; source "
                                 f"{s['flicker_mc_source']:.3f})", s["flicker_mc_output"], "", None))
            if "undeclared_obstacles" in s:
                u = s["undeclared_obstacles"]
                where = "; ".join(f"node ({c['center'][0]} {c['center'][1]}) r~{c['radius']}" for c in u)
                rows.append(_row(item, "dark still regions ringed by moving fluid that no in_footage obstacle covers (heuristic "
                                 f"warning{': ' + where if u else ''})", float(len(u)), "", None))
            rows.append(_row(item, "render s/frame", s["render_s_per_frame"], "", None))
            rows.append(_row(item, "optimisation s", s["optimise_s"], "", None))
        else:
            raise ValueError(f"summary with keys {sorted(s)} is not a fluid_flow, fluid_middlebury or fluid_edit summary")
    return rows


def rows_to_csv(rows: list[dict[str, Any]]) -> str:
    """CSV text (header + rows); floats with 4 significant decimals."""
    def cell(v: Any) -> str:
        t = f"{v:.4f}" if isinstance(v, float) else str(v)
        return f'"{t}"' if "," in t else t
    return ",".join(COLUMNS) + "\n" + "".join(",".join(cell(r[c]) for c in COLUMNS) + "\n" for r in rows)
