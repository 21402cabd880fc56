"""Stage ``fluid_edit``: a source-sink edit of fluid footage, optimised and rendered (seed 5.2-5.4).

``python -m vidsim.cli.fluid_edit fluid.edit.spec=docs/fluid_edits/waterfall_widen.yaml
paths.footage=results/footage/fluid_waterfall fluid.edit.flow=results/fluid/flow/fluid_waterfall/flow.npz
paths.out=results/fluid/edit/fluid_waterfall/waterfall_widen`` (the pipeline's layout:
``fluid/edit/<footage>/<edit>/``; the optimiser's checkpoint goes beside the output folder)

The edit YAML (``docs/fluid_editing.md``) names its footage with ``footage:``
(``synthetic:<scene>`` -> ``<results>/footage/fluid_<scene>``, ``piv:<name>`` ->
``<results>/footage/piv_<name>``, or a folder path); ``paths.footage`` may be left empty to use
it. The optimiser checkpoints its state every ``fluid.edit.checkpoint_every`` iterations to
``<out>/../.<name>.ckpt.npz``; a rerun after a kill resumes from it (to the same result as an
uninterrupted run) and removes it on success.

Outputs (folder written under a temporary name, renamed at the end): ``edit.mp4`` (the
rendered frames), ``edit.gif`` (source | output, for the report), ``contact_sheet.png``,
``arrows.png`` (the video's mean field before, the edited field after, with sources, sinks,
obstacles and particle exits), ``summary.json``/``summary.csv`` (sink fractions, rendered-flow
EPE, patch-distance and detail-contrast ratios, flicker in static regions and motion-compensated,
timings), ``field.npz``, ``fluid.rrd``.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import sys
import time
import warnings
import zipfile
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.errors import ConfigError, FootageError
from vidsim.fluid.edit import EditSpec, EditSpecError
from vidsim.fluid.footage import resolve_footage
from vidsim.fluid.flow import estimate_flow
from vidsim.fluid.pipeline import (UndeclaredObstacleWarning, run_edit, undeclared_obstacle_message, undeclared_obstacles,
                                   video_fields)
from vidsim.fluid.viz import arrow_grid
from vidsim.io.atomic import atomic_path, replace_dir, to_json, write_json, write_npz, write_text
from vidsim.io.footage import load_yaml, read_footage
from vidsim.log import make_logger

#: widest edit.gif (footage | edit side by side) in pixels; wider pairs are scaled down
GIF_MAX_WIDTH = 1024
from vidsim.log.progress import Progress
from vidsim.report.figures import contact_sheet, save_figure


def load_edit(path: str | Path) -> tuple[EditSpec, dict[str, Any]]:
    """Read and validate an edit YAML; errors name the file and the key."""
    if not str(path).strip():
        raise ConfigError("fluid.edit.spec is empty: give the edit YAML (e.g. docs/fluid_edits/waterfall_widen.yaml)")
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"fluid.edit.spec={str(path)!r}: edit file is missing")
    d = load_yaml(path, ConfigError, "edit file")
    if not isinstance(d, dict):
        raise ConfigError(f"{path}: expected a mapping of edit keys, got {type(d).__name__}")
    try:
        return EditSpec.from_dict(d), d
    except ValueError as e:
        raise ConfigError(f"{path}: {e}") from None


def write_video(path: Path, frames: np.ndarray, fps: float) -> None:
    """H.264 mp4 of ``(T, H, W, 3)`` uint8 frames (padded to even size), written atomically."""
    import av

    T, H, W, _ = frames.shape
    He, We = H + H % 2, W + W % 2
    with atomic_path(path) as tmp:
        with av.open(str(tmp), mode="w", format="mp4") as c:
            st = c.add_stream("libx264", rate=int(round(fps)))
            st.width, st.height, st.pix_fmt = We, He, "yuv420p"
            st.options = {"crf": "18", "preset": "medium", "threads": "1"}
            for f in frames:
                if (He, We) != (H, W):
                    f = np.pad(f, ((0, He - H), (0, We - W), (0, 0)), mode="edge")
                for pkt in st.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(f), format="rgb24")):
                    c.mux(pkt)
            for pkt in st.encode():
                c.mux(pkt)


def write_gif(path: Path, frames: np.ndarray, fps: float) -> None:
    """Animated GIF of ``(T, H, W, 3)`` uint8 frames, written atomically."""
    from PIL import Image

    ims = [Image.fromarray(f) for f in frames]
    with atomic_path(path) as tmp:
        ims[0].save(tmp, format="GIF", save_all=True, append_images=ims[1:], duration=int(1000 / fps), loop=0)


def _draw_spec(ax, spec: EditSpec, ds: int) -> None:
    from matplotlib.patches import Ellipse, Rectangle

    for s in spec.sinks:
        x0, y0, x1, y1 = s.box
        ax.add_patch(Rectangle((x0 * ds, y0 * ds), (x1 - x0) * ds, (y1 - y0) * ds, fill=False, ec="lime", lw=1.2))
        ax.text(x0 * ds, y0 * ds, s.name, color="lime", fontsize=6, va="bottom")
    for s in spec.sources:
        x0, y0, x1, y1 = s.box
        ax.add_patch(Rectangle((x0 * ds, y0 * ds), (x1 - x0) * ds, (y1 - y0) * ds, fill=False, ec="cyan", lw=1.2))
    for o in spec.obstacles:
        if o.box is not None:
            x0, y0, x1, y1 = o.box
            ax.add_patch(Rectangle((x0 * ds, y0 * ds), (x1 - x0) * ds, (y1 - y0) * ds, fill=False, ec="red", lw=1.0))
        else:
            ax.add_patch(Ellipse((o.center[0] * ds, o.center[1] * ds), 2 * o.radii[0] * ds, 2 * o.radii[1] * ds,
                                 fill=False, ec="red", lw=1.0))


def _arrow_figure(path: Path, spec: EditSpec, bg: np.ndarray, before: np.ndarray, after: np.ndarray,
                  res: Any, step: int, title: str) -> None:
    import matplotlib.pyplot as plt

    ds = spec.downsample
    fig, axes = plt.subplots(1, 2, figsize=(10, 5.2))
    # one arrow scale for both panels (each panel's own had drawn the slower field the longer; review)
    vmax = max(max(float(np.percentile(np.linalg.norm(f, axis=-1), 95)) for f in (before, after)), 1e-6)
    for ax, f, name in ((axes[0], before, "before: the footage's mean flow"), (axes[1], after, "after: the edited field")):
        name += f" (arrow of one cell = {vmax:.2f} px/frame, both panels)"
        ax.imshow(bg)
        o, v = arrow_grid(f, step, scale=0.9 * step / vmax)
        ax.quiver(o[:, 0], o[:, 1], v[:, 0], v[:, 1], color="yellow", angles="xy", scale_units="xy", scale=1, width=0.003)
        _draw_spec(ax, spec, ds)
        ax.set_title(name, fontsize=9)
        ax.axis("off")
    ok = res.codes == res.desired
    ex = res.exits * ds
    axes[1].scatter(ex[ok, 0], ex[ok, 1], s=6, c="lime", label="exit in desired sink")
    axes[1].scatter(ex[~ok, 0], ex[~ok, 1], s=10, c="red", marker="x", label="exit elsewhere")
    axes[1].legend(loc="lower right", fontsize=6)
    fig.suptitle(title, fontsize=9)
    save_figure(fig, path)


def _spec_key(raw: dict, n_frames: int, iterations: int, footage: Path, flow: np.ndarray) -> str:
    """What a checkpoint belongs to: the edit, its settings and the flow it was optimised on."""
    txt = json.dumps({"spec": raw, "frames": n_frames, "iterations": iterations, "footage": footage.name}, sort_keys=True, default=str)
    h = hashlib.sha256(txt.encode())
    h.update(np.ascontiguousarray(flow, dtype=np.float32).tobytes())
    return h.hexdigest()[:16]


CHECKPOINT_ARRAYS = ("key", "v", "step", "it", "hist")


def _read_checkpoint(ckpt: Path, key: str) -> dict[str, np.ndarray] | None:
    """The optimiser state of ``ckpt`` if it belongs to ``key`` (None if absent or of other
    settings); a file that is not a readable checkpoint is a one-line :class:`ConfigError`
    naming it (it is not deleted: it may be somebody's file)."""
    if not ckpt.is_file():
        return None
    try:
        with np.load(ckpt, allow_pickle=False) as z:
            missing = [k for k in CHECKPOINT_ARRAYS if k not in z.files]
            if missing:
                raise ConfigError(f"{ckpt}: not a fluid_edit checkpoint (no array(s) {missing}; arrays: {z.files}); "
                                  "delete it to start the optimisation afresh")
            if str(z["key"]) != key:
                print(f"fluid_edit: ignoring checkpoint {ckpt} of a different edit/settings", flush=True)
                return None
            resume = {k: z[k] for k in CHECKPOINT_ARRAYS[1:]}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise ConfigError(f"{ckpt}: unreadable fluid_edit checkpoint ({type(e).__name__}: {e}); "
                          "delete it to start the optimisation afresh") from None
    print(f"fluid_edit: resuming the optimisation at iteration {int(resume['it'])} from {ckpt}", flush=True)
    return resume


def run(cfg: DictConfig) -> None:
    ec = cfg.fluid.edit
    spec, raw = load_edit(ec.spec)
    if ec.iterations is not None:
        if ec.iterations < 0:
            raise ConfigError(f"fluid.edit.iterations={ec.iterations}, expected >= 0")
        raw = {**raw, "optimizer": {**(raw.get("optimizer") or {}), "iterations": int(ec.iterations)}}
        spec = EditSpec.from_dict(raw)
    if ec.checkpoint_every < 1:
        raise ConfigError(f"fluid.edit.checkpoint_every={ec.checkpoint_every}, expected >= 1 iteration")
    if not (np.isfinite(float(ec.video_fps)) and float(ec.video_fps) > 0):
        raise ConfigError(f"fluid.edit.video_fps={ec.video_fps} is not valid: expected a finite rate > 0 fps")
    if int(ec.gif_frames) < 1:
        raise ConfigError(f"fluid.edit.gif_frames={ec.gif_frames}, expected >= 1 frame")
    n_frames = int(ec.frames) if ec.frames is not None else spec.render.frames
    if n_frames < 2:
        where = "fluid.edit.frames" if ec.frames is not None else f"{ec.spec}: render.frames"
        raise ConfigError(f"{where}={n_frames}, expected >= 2 output frames")
    label_folder = resolve_footage(spec.footage, cfg.paths.results) if spec.footage else None
    folder = Path(cfg.paths.footage) if cfg.paths.footage else label_folder
    if folder is None:
        raise ConfigError(f"{ec.spec}: no 'footage:' in the edit and paths.footage is empty")
    if label_folder is not None and spec.footage.split(":")[0] in ("synthetic", "piv") and folder.name != label_folder.name:
        raise ConfigError(f"paths.footage={str(folder)!r} is not the footage the edit names "
                          f"(footage: {spec.footage} -> {label_folder.name})")
    foot = read_footage(folder)  # FootageError naming the folder if it is missing
    frames = foot.frames
    if ec.flow:
        fp = Path(ec.flow)
        if not fp.is_file():
            raise FootageError(f"fluid.edit.flow={str(fp)!r}: flow file is missing")
        try:
            with np.load(fp, allow_pickle=False) as z:
                if "flow" not in z.files:
                    raise FootageError(f"{fp}: no array 'flow' (arrays: {z.files}); give fluid_flow's flow.npz")
                flow = z["flow"]
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
            raise FootageError(f"{fp}: not a readable .npz, truncated or not written by fluid_flow ({e})") from None
        if flow.shape != (frames.shape[0] - 1, *frames.shape[1:3], 2):
            raise FootageError(f"{fp}: flow shape {flow.shape} does not fit the footage {frames.shape}")
        if not np.all(np.isfinite(flow)):
            raise FootageError(f"{fp}: 'flow' has non-finite values (px/frame expected)")
    else:
        flow = estimate_flow(frames, temporal_sigma=float(cfg.fluid.flow.temporal_sigma))
    video_fields(flow[:1], spec)  # the grid must fit the footage (clear error before optimising)
    undeclared = undeclared_obstacles(frames, flow, spec)
    for u in undeclared:  # before the long part, one line each
        print(f"fluid_edit: WARNING: {ec.spec}: {undeclared_obstacle_message(u)}", file=sys.stderr, flush=True)
    out = Path(cfg.paths.out)
    ckpt = out.parent / f".{out.name}.ckpt.npz"
    key = _spec_key(raw, n_frames, spec.optimizer.iterations, folder, flow)
    resume = _read_checkpoint(ckpt, key)
    iters = spec.optimizer.iterations
    bars: dict[str, Progress] = {}  # made at the first step, so their clocks start there

    def on_iter(it: int, state: dict[str, Any]) -> None:
        if "opt" not in bars:
            bars["opt"] = Progress(iters, f"fluid_edit {out.name} optimise (max iterations)", enabled=cfg.log.progress)
            bars["opt"].i = it - 1
        bars["opt"].update(it - bars["opt"].i, note=f"E={state['hist'][-1]:.4g} step={state['step']:.3g}")
        if it % int(ec.checkpoint_every) == 0:
            write_npz(ckpt, key=np.array(key), **state)

    def on_frame(n: int) -> None:
        if "ren" not in bars:
            bars["ren"] = Progress(n_frames, f"fluid_edit {out.name} render frames", enabled=cfg.log.progress)
        bars["ren"].update()

    t0 = time.perf_counter()
    with warnings.catch_warnings():  # said above, in one line each
        warnings.simplefilter("ignore", UndeclaredObstacleWarning)
        try:
            r = run_edit(frames, spec, np.random.default_rng(cfg.seed + spec.render.seed), n_frames, flow=flow,
                         resume=resume, on_iter=on_iter, on_frame=on_frame)
        except EditSpecError as e:  # a diverged optimisation, a grid the footage does not give
            raise ConfigError(f"{ec.spec}: {e}") from None
    total = time.perf_counter() - t0
    res, figs, outf = r["edit"], r["figures"], r["frames"]
    print(f"fluid_edit: optimisation stopped after {res.figures['iterations']} iterations "
          f"({res.figures['time_s']:.1f} s); the streamlines of {100 * res.figures['fraction_in_desired_sink']:.1f} % "
          f"of {len(res.desired)} source particles end in their desired sink "
          f"({100 * res.figures['fraction_in_desired_sink_init']:.1f} % at initialisation; median "
          f"{res.figures['arrival_frames_median']:.0f} frames to get there, "
          f"{100 * figs['fraction_arriving_within_render']:.1f} % within the {n_frames} rendered frames)", flush=True)
    names = [s.name for s in spec.sinks]
    per_sink = {}
    for k, nm in enumerate(names):
        m = res.desired == k
        if m.any():
            per_sink[nm] = float(np.mean(res.codes[m] == k))
    ds = spec.downsample
    H, W = outf.shape[1:3]
    summary = {
        "edit": out.name, "footage": folder.name, "description": spec.description,
        "particles": int(len(res.desired)),
        "fraction_in_desired_sink": float(res.figures["fraction_in_desired_sink"]),
        "fraction_in_desired_sink_init": float(res.figures["fraction_in_desired_sink_init"]),
        "fraction_in_desired_sink_per_sink": per_sink,
        "arrival_frames_median": float(res.figures["arrival_frames_median"]),
        "arrival_frames_max": float(res.figures["arrival_frames_max"]),
        "fraction_arriving_within_render": float(figs["fraction_arriving_within_render"]),
        "undeclared_obstacles": undeclared,
        "iterations": int(res.figures["iterations"]), "objective": float(res.figures["E"]),
        "rendered_flow_epe_px": float(figs["rendered_flow_epe_px"]),
        "edited_speed_mean_px": float(figs["edited_speed_mean_px"]),
        "rendered_flow_epe_rel": float(figs["rendered_flow_epe_rel"]),
        "edited_speed_epe_mask_px": float(figs["edited_speed_epe_mask_px"]),
        "patch_distance_ratio": float(figs["patch_distance"]["ratio"]),
        "patch_coherence_ratio": float(figs["patch_distance"]["coherence_ratio"]),
        "patch_completeness_ratio": float(figs["patch_distance"]["completeness_ratio"]),
        "detail_ratio": float(figs["detail_ratio"]),
        **{k: float(figs[k]) for k in ("footage_obstacle_grey_output", "footage_obstacle_grey_source")},
        "flicker_output": float(figs["flicker_output"]), "flicker_source": float(figs["flicker_source"]),
        "flicker_mc_output": float(figs["flicker_mc_output"]), "flicker_mc_source": float(figs["flicker_mc_source"]),
        "static_fraction": float(figs["static_fraction"]),
        "static_fraction_output": float(figs["static_fraction_output"]),
        "static_fraction_source": float(figs["static_fraction_source"]),
        "frames": int(n_frames), "width": int(W), "height": int(H),
        "optimise_s": float(res.figures["time_s"]), "render_s_per_frame": float(figs["render"]["time_per_frame_s"]),
        "total_s": total, "resumed_from_iteration": int(resume["it"]) if resume is not None else 0,
    }
    print("fluid_edit: " + ", ".join(f"{k} {summary[k]:.3f}" for k in (
        "fraction_in_desired_sink", "rendered_flow_epe_px", "rendered_flow_epe_rel", "patch_distance_ratio",
        "detail_ratio", "flicker_output", "flicker_source")), flush=True)
    tmp = out.with_name(f".{out.name}.part")
    shutil.rmtree(tmp, ignore_errors=True)
    src = frames[:, :H, :W]
    video_mean = flow[:, :H, :W].mean(0)
    with make_logger(tmp / "fluid.rrd", "vidsim.fluid_edit", cfg.log.rerun) as lg:
        step = max(4, 4 * ds)
        oa, va = arrow_grid(r["edited_field_px"], step, scale=3.0)
        for i in range(n_frames):
            lg.set_frame(i)
            lg.image("footage/camera/image", src[i % src.shape[0]])
            if i < flow.shape[0]:
                o, v = arrow_grid(flow[i, :H, :W], step, scale=3.0)
                lg.arrows2d("footage/camera/flow", o, v)
            lg.image("sim/camera/image", outf[i])
            lg.arrows2d("sim/camera/field", oa, va)
        lg.series("metric/rendered_flow_epe_px", r["epe_frames"], timeline="frame")
        lg.series("optim/objective", np.asarray(res.history), timeline="iter")
        lg.text("log", to_json(summary))
        write_video(tmp / "edit.mp4", outf, float(ec.video_fps))
        g = np.linspace(0, n_frames - 1, min(int(ec.gif_frames), n_frames)).round().astype(int)
        sep = np.full((H, 2, 3), 255, np.uint8)
        pairs = np.stack([np.concatenate([src[i % src.shape[0]], sep, outf[i]], 1) for i in g])
        if pairs.shape[2] > GIF_MAX_WIDTH:  # the report's preview: 24 full-resolution PIV frames made a 30 MB GIF
            f = GIF_MAX_WIDTH / pairs.shape[2]
            size = (GIF_MAX_WIDTH, max(1, round(pairs.shape[1] * f)))
            pairs = np.stack([cv2.resize(p, size, interpolation=cv2.INTER_AREA) for p in pairs])
        write_gif(tmp / "edit.gif", pairs, float(ec.video_fps) / max(1, n_frames // max(len(g), 1)))
        contact_sheet(outf, tmp / "contact_sheet.png")
        _arrow_figure(tmp / "arrows.png", spec, src.mean(0).astype(np.uint8), video_mean, r["edited_field_px"], res,
                      step * 2, f"{out.name}: streamlines of {100 * summary['fraction_in_desired_sink']:.1f} % of "
                      f"{summary['particles']} source particles end in their desired sink")
        write_npz(tmp / "field.npz", field_nodes=res.field, field_px=r["edited_field_px"].astype(np.float32),
                  video_mean_px=video_mean.astype(np.float32), exits=res.exits, codes=res.codes, desired=res.desired)
        # strict JSON: a figure that cannot be measured (flicker without a static region: NaN) is null there
        write_json(tmp / "summary.json", summary)
        flat = {k: v for k, v in summary.items() if not isinstance(v, (dict, list))}
        flat["undeclared_obstacles"] = len(undeclared)
        flat.update({f"fraction_in_sink_{k}": v for k, v in per_sink.items()})
        write_text(tmp / "summary.csv", "quantity,value\n" + "".join(f"{k},{v}\n" for k, v in flat.items()))
    replace_dir(tmp, out)
    ckpt.unlink(missing_ok=True)


main = stage_app("fluid_edit", run)

if __name__ == "__main__":
    main()
