"""Stage-level drivers of the fluid pipeline, for the lead's CLI and Snakemake rules.

Each takes plain arrays and dicts and returns arrays plus a dict of measured figures:

``footage frames -> estimate_flow -> video_fields -> edit_field -> render_sequence -> figures``.
No file I/O here; reading footage and writing results belong to ``vidsim.io`` / the CLI.
"""

from __future__ import annotations

import warnings
from typing import Any, Callable

import cv2
import numpy as np

from vidsim.fluid.edit import EditSpec, EditSpecError
from vidsim.fluid.flow import FlowMethod, estimate_flow
from vidsim.fluid.metrics import (MIN_STATIC_PX, compensated_flicker, detail_contrast, obstacle_grey, patch_distance_ratio,
                                  relative_epe, rendered_flow_epe_frames, static_flicker)
from vidsim.fluid.optimize import EditResult, edit_field
from vidsim.fluid.render import Transplant, downsample_flow, render_sequence, upsample_field


class UndeclaredObstacleWarning(UserWarning):
    """The footage seems to hold a solid that the edit does not declare as an obstacle."""


def prepare_gray_frames(frames: list[np.ndarray] | np.ndarray, downsample: int = 1) -> np.ndarray:
    """Grey (or colour) recordings such as PIV images to ``(T, H, W, 3)`` uint8 RGB, area-
    downsampled by an integer factor (the PIVlab frames are 1024x765: ``downsample=4`` gives
    256x191)."""
    out = []
    for i, f in enumerate(frames):
        f = np.asarray(f)
        if f.dtype != np.uint8:
            raise ValueError(f"frames[{i}] dtype {f.dtype}, expected uint8")
        if downsample > 1:
            f = cv2.resize(f, (f.shape[1] // downsample, f.shape[0] // downsample), interpolation=cv2.INTER_AREA)
        if f.ndim == 2:
            f = np.repeat(f[..., None], 3, axis=-1)
        out.append(f)
    return np.stack(out)


def video_fields(flow: np.ndarray, spec: EditSpec) -> np.ndarray:
    """Optical flow ``(T-1, H, W, 2)`` px/frame to the edit grid ``(T-1, h, w, 2)`` nodes/frame."""
    g = downsample_flow(flow, spec.downsample)
    if g.shape[1] < spec.height or g.shape[2] < spec.width:
        raise EditSpecError(f"footage gives a {g.shape[2]}x{g.shape[1]} grid at downsample={spec.downsample}, "
                            f"smaller than the edit's grid {spec.width}x{spec.height} (width, height): give the edit a "
                            f"grid of at most {g.shape[2]}x{g.shape[1]}, or a smaller downsample")
    return g[:, :spec.height, :spec.width]


def obstacle_transplants(spec: EditSpec, size: tuple[int, int]) -> list[Transplant]:
    """The obstacles the edit adds, as :class:`Transplant` s on the ``size`` = (H, W) output
    (nodes of ``spec.downsample`` px; node ``n`` covers pixels ``[n ds, (n + 1) ds)``, so its
    centre is pixel ``n ds + (ds - 1) / 2``), each from the ``in_footage`` obstacle
    :meth:`EditSpec.transplant_sources` chooses; none without an ``in_footage`` obstacle."""
    H, W = size
    ds = spec.downsample
    out = []
    for o, j in zip(spec.obstacles, spec.transplant_sources()):
        if j is None:
            continue
        (cx, cy), (hx, hy) = o.extent()
        (sx, sy), (gx, gy) = spec.obstacles[j].extent()
        mask = cv2.resize(o.mask(spec.height, spec.width).astype(np.uint8), (W, H),
                          interpolation=cv2.INTER_NEAREST).astype(bool)
        out.append(Transplant(mask, (cx * ds + (ds - 1) / 2, cy * ds + (ds - 1) / 2),
                              (sx * ds + (ds - 1) / 2, sy * ds + (ds - 1) / 2), (gx / hx, gy / hy)))
    return out


def undeclared_obstacle_message(u: dict[str, Any]) -> str:
    """The warning for one region :func:`undeclared_obstacles` found (the pipeline's
    :class:`UndeclaredObstacleWarning` and ``fluid_edit``'s printed line say the same)."""
    return (f"the footage has a dark, still region around node ({u['center'][0]}, {u['center'][1]}) ({u['nodes']} "
            f"nodes, radius ~{u['radius']}) with moving fluid around it that no 'in_footage: true' obstacle of the edit "
            "covers: if it is a solid in the footage, declare it under 'obstacles' with in_footage: true "
            "(docs/fluid_editing.md), or the edited field flows through it and the render paints it out")


def undeclared_obstacles(src_frames: np.ndarray, flow: np.ndarray, spec: EditSpec, dark: float = 0.3,
                         still: float = 0.2, moving_around: float = 0.2, min_nodes: int = 16) -> list[dict[str, Any]]:
    """Regions of the footage that look like a solid the edit does not declare: dark, unchanging
    and ringed by moving fluid (a cylinder in a PIV recording). A heuristic for a warning, not a
    segmentation; on the edit grid (node means, blurred 1 node):

    * dark: time-mean grey level below ``dark`` x its median over the grid;
    * unchanging: mean absolute frame-to-frame change of grey level below ``still`` x its 90th
      percentile (the appearance, not the optical flow, which smears motion into flat regions);
    * a connected region of at least ``min_nodes`` such nodes, not touching the grid's edge (a
      dark still background, e.g. behind a flame, does), whose ring 3-6 nodes out moves: median
      speed of the time-mean flow at least ``moving_around`` x its 90th percentile (dark still
      patches inside a background are ringed by more background: at most 0.05 on the example
      footages, against 0.39 around the PIV cylinder);
    * at most half of it covered by obstacles declared ``in_footage`` (an obstacle the edit adds
      there would be drawn over the footage's solid, not show it).

    Returns:
        one dict per region: ``center`` [x, y] and equivalent ``radius`` (nodes), ``nodes``.
    """
    from scipy import ndimage as ndi

    h, w, ds = spec.height, spec.width, spec.downsample
    sp = np.linalg.norm(video_fields(flow, spec).mean(0), axis=-1)
    g = src_frames[:, :h * ds, :w * ds].astype(np.float32).mean(-1)

    def nodes(a: np.ndarray) -> np.ndarray:
        return cv2.GaussianBlur(a.reshape(h, ds, w, ds).mean((1, 3)), (0, 0), 1.0)

    grey = nodes(g.mean(0))
    change = nodes(np.abs(np.diff(g, axis=0)).mean(0)) if len(g) > 1 else np.zeros((h, w), np.float32)
    p90, c90 = float(np.percentile(sp, 90)), float(np.percentile(change, 90))
    if p90 <= 0 or c90 <= 0:
        return []
    lab, n = ndi.label((grey < dark * float(np.median(grey))) & (change < still * c90))
    solid, shown = spec.solid_mask(), spec.solid_mask(in_footage=True)
    found = []
    for k in range(1, n + 1):
        c = lab == k
        yy, xx = np.nonzero(c)
        if c.sum() < min_nodes or yy.min() == 0 or xx.min() == 0 or yy.max() == h - 1 or xx.max() == w - 1:
            continue
        if (c & shown).sum() > 0.5 * c.sum():
            continue
        ring = ndi.binary_dilation(c, iterations=6) & ~ndi.binary_dilation(c, iterations=2) & ~solid
        if not ring.any() or np.median(sp[ring]) < moving_around * p90:
            continue
        found.append({"center": [round(float(xx.mean()), 1), round(float(yy.mean()), 1)],
                      "radius": round(float(np.sqrt(c.sum() / np.pi)), 1), "nodes": int(c.sum())})
    return found


def run_edit(src_frames: np.ndarray, spec: EditSpec, rng: np.random.Generator, n_frames: int | None = None,
             method: FlowMethod = "dis_fine", temporal_sigma: float = 1.0,
             flow: np.ndarray | None = None, resume: dict[str, Any] | None = None,
             on_iter: Callable[[int, dict[str, Any]], None] | None = None,
             on_frame: Callable[[int], None] | None = None) -> dict[str, Any]:
    """Flow -> edit -> render -> measure, for one edit.

    Args:
        src_frames: ``(T, H, W, 3)`` uint8 footage.
        spec: the edit (grid coordinates in nodes of ``spec.downsample`` pixels).
        rng: random generator for the renderer.
        n_frames: output frames (default ``spec.render.frames``).
        method, temporal_sigma: optical-flow settings (see :func:`estimate_flow`).
        flow: precomputed flow of ``src_frames`` (skips the estimate).
        resume, on_iter: optimiser checkpoint state and per-iteration callback
            (:func:`vidsim.fluid.optimize.optimize_field`).
        on_frame: per-output-frame callback of the renderer (progress).

    Returns:
        dict with ``frames`` (n,H',W',3) uint8, ``edited_field_px`` (H',W',2), ``edit``
        (:class:`EditResult`), ``source_flow`` and ``figures`` (flow-conservation fraction,
        rendered-flow EPE in px/frame and relative to the edited field's mean speed on the same
        pixels, patch-distance ratio, detail-contrast ratio, flicker of output and source in grey
        levels on the pixels static in both, declared obstacles excluded (NaN: fewer than
        ``MIN_STATIC_PX`` such pixels) and motion-compensated over the whole frame, timings)
        and ``epe_frames`` (n-1,) the rendered-flow EPE per frame pair. The figures'
        ``undeclared_obstacles`` lists what :func:`undeclared_obstacles` found (each also
        issued as an :class:`UndeclaredObstacleWarning`).
    """
    n = spec.render.frames if n_frames is None else n_frames
    if flow is None:
        flow = estimate_flow(src_frames, method=method, temporal_sigma=temporal_sigma)
    g = video_fields(flow, spec)
    undeclared = undeclared_obstacles(src_frames, flow, spec)
    for u in undeclared:
        warnings.warn(undeclared_obstacle_message(u), UndeclaredObstacleWarning, stacklevel=2)
    step = max(1, g.shape[0] // 12)
    res: EditResult = edit_field(g.mean(0), spec, g[::step], resume=resume, on_iter=on_iter)
    if not res.ok:  # said before the render, which would take minutes for nothing
        raise EditSpecError(f"the optimisation became non-finite (objective NaN/inf) after "
                            f"{res.figures.get('iterations', 0)} iterations; check the edit's weights and step")
    ds = spec.downsample
    H, W = spec.height * ds, spec.width * ds
    field_px = upsample_field(res.field, ds, (H, W))
    solid_px, footage_px = (cv2.resize(spec.solid_mask(f).astype(np.uint8), (W, H), interpolation=cv2.INTER_NEAREST)
                            .astype(bool) for f in (None, True))
    field_px[solid_px] = 0.0
    # the edit was optimised against the time-mean flow: match velocity patches on it too; the
    # obstacles in the footage show its own pixels, the ones the edit adds their appearance
    transplants = obstacle_transplants(spec, (H, W)) if spec.render.added_obstacles == "transplant" else []
    out, rfig = render_sequence(src_frames[:, :H, :W], flow[:, :H, :W], field_px, n, rng, spec.render, solid_px,
                                match_flow=flow[:, :H, :W].mean(0), footage_solid=footage_px,
                                transplants=transplants, on_frame=on_frame)
    figs: dict[str, Any] = {"edit": dict(res.figures), "render": rfig, "undeclared_obstacles": undeclared}
    # streamlines end in their sink (the optimiser's figure); how many particles would get there
    # within the rendered clip, moving at the field's speed (frames = nodes / (nodes/frame))
    figs["fraction_arriving_within_render"] = float(np.mean((res.codes == res.desired) & (res.arrival_frames <= n)))
    src = src_frames[:, :H, :W]
    out_flow = estimate_flow(out)
    border = spec.render.patch
    epe_frames = rendered_flow_epe_frames(out, field_px, border=border, flow=out_flow)
    figs["rendered_flow_epe_px"] = float(epe_frames.mean())
    figs["edited_speed_mean_px"] = float(np.linalg.norm(field_px, axis=-1).mean())
    # the EPE's scale: the field's mean speed on the same pixels (what a frozen render scores)
    figs["rendered_flow_epe_rel"], figs["edited_speed_epe_mask_px"] = relative_epe(figs["rendered_flow_epe_px"], field_px,
                                                                                    border)
    figs["patch_distance"] = patch_distance_ratio(out, src, rng=rng)
    figs["detail_ratio"] = detail_contrast(out) / max(detail_contrast(src), 1e-12)
    figs.update(obstacle_grey(out, src, footage_px))
    # static flicker, output and source scored on ONE mask: pixels static in both (edited field and
    # time-median source flow < 0.1 px/frame), declared obstacles excluded (the renderer holds its
    # source frame there, so they cannot flicker; counting them flattered the output)
    figs.update(static_flicker(out, src, field_px, flow[:, :H, :W], solid_px, MIN_STATIC_PX))
    # along each sequence's own (unsmoothed) optical flow, whole frame
    figs["flicker_mc_output"] = compensated_flicker(out, out_flow, border)
    figs["flicker_mc_source"] = compensated_flicker(src, estimate_flow(src), border)
    return {"frames": out, "edited_field_px": field_px, "edit": res, "source_flow": flow, "figures": figs,
            "epe_frames": epe_frames}
