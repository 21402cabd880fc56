"""Stage ``fluid_flow``: the velocity field of fluid footage by optical flow, scored against truth.

``python -m vidsim.cli.fluid_flow paths.footage=results/footage/fluid_waterfall paths.out=results/fluid/flow/fluid_waterfall``.
The estimate reads only the footage frames. Afterwards, when the footage is synthetic (a truth
file lies beside the folder), the stage scores the estimate and OpenCV's DIS medium preset
(``fluid.flow.baseline``) against the true velocity: average endpoint error per frame pair.

Outputs: ``flow.npz`` (``flow`` (T-1,H,W,2) float32 px/frame, the edit stage's input),
``summary.json`` / ``summary.csv``, ``flow.png`` (frames, colour-coded estimated and true flow,
error map, colour wheel), ``flow.rrd`` (footage, flow arrows, EPE per frame).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.errors import ConfigError, FootageError
from vidsim.fluid.flow import endpoint_error, estimate_flow
from vidsim.fluid.viz import arrow_grid, color_wheel, flow_to_color
from vidsim.io.atomic import write_json, write_npz, write_text
from vidsim.io.footage import read_footage, read_truth, truth_path
from vidsim.log import make_logger
from vidsim.log.progress import Progress
from vidsim.report.figures import save_figure

METHODS = ("dis_fine", "dis_medium", "farneback")


def _load_truth(folder: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """The true velocity ``(T-1,H,W,2)`` and dye ``(T,H,W)`` of a synthetic footage folder, or
    None for a real recording."""
    if not truth_path(folder).is_file():
        return None
    t = read_truth(folder)
    with np.load(truth_path(folder).with_name(t["arrays"])) as z:
        return z["velocity"].astype(np.float32), z["dye"].astype(np.float32)


def _figure(frames: np.ndarray, flow: np.ndarray, truth: np.ndarray | None, path: Path, title: str, step: int) -> None:
    import matplotlib.pyplot as plt

    idx = np.unique(np.linspace(0, flow.shape[0] - 1, min(3, flow.shape[0])).round().astype(int))
    ncol = 4 if truth is not None else 3
    fig, axes = plt.subplots(len(idx), ncol, figsize=(3.0 * ncol, 2.9 * len(idx)), squeeze=False)
    for r, i in enumerate(idx):
        vmax = float(np.percentile(np.linalg.norm(truth[i] if truth is not None else flow[i], axis=-1), 99)) + 1e-6
        axes[r, 0].imshow(frames[i])
        o, v = arrow_grid(flow[i], step, scale=step / (2 * vmax))
        axes[r, 0].quiver(o[:, 0], o[:, 1], v[:, 0], v[:, 1], color="yellow", angles="xy", scale_units="xy", scale=1, width=0.004)
        axes[r, 0].set_title(f"frame {i} + estimated flow", fontsize=8)
        axes[r, 1].imshow(flow_to_color(flow[i], vmax))
        axes[r, 1].set_title(f"estimated (full colour = {vmax:.2f} px/frame)", fontsize=8)
        if truth is not None:
            axes[r, 2].imshow(flow_to_color(truth[i], vmax))
            axes[r, 2].set_title("true velocity", fontsize=8)
            err = np.linalg.norm(flow[i] - truth[i], axis=-1)
            im = axes[r, 3].imshow(err, cmap="magma", vmin=0, vmax=max(vmax, 1e-3))
            axes[r, 3].set_title(f"endpoint error, mean {err.mean():.3f} px", fontsize=8)
            fig.colorbar(im, ax=axes[r, 3], fraction=0.046)
        else:
            axes[r, 2].imshow(color_wheel(128))
            axes[r, 2].set_title("colour wheel (direction, speed)", fontsize=8)
    for ax in axes.ravel():
        ax.axis("off")
    fig.suptitle(title, fontsize=9)
    save_figure(fig, path)


def run(cfg: DictConfig) -> None:
    fc = cfg.fluid.flow
    for key in ("method", "baseline"):
        if fc[key] not in METHODS:
            raise ConfigError(f"fluid.flow.{key}={fc[key]!r}, expected one of {METHODS}")
    from vidsim.config.fluid import check_fluid_numbers

    check_fluid_numbers(fc, "fluid.flow", {"arrow_step": ("int", 0)})
    if fc.temporal_sigma < 0:
        raise ConfigError(f"fluid.flow.temporal_sigma={fc.temporal_sigma}, expected >= 0 frames")
    if not str(cfg.paths.footage).strip():
        raise ConfigError("paths.footage is empty: give the fluid footage folder")
    folder = Path(cfg.paths.footage)
    foot = read_footage(folder)
    frames = foot.frames
    if frames.shape[0] < 2:
        raise FootageError(f"{folder}: {frames.shape[0]} frame(s); the flow needs at least 2")
    out = Path(cfg.paths.out)
    name = folder.name
    t0 = time.perf_counter()
    flow = estimate_flow(frames, method=fc.method, temporal_sigma=float(fc.temporal_sigma))
    t_flow = time.perf_counter() - t0
    print(f"fluid_flow: {name}: {flow.shape[0]} pairs {frames.shape[2]}x{frames.shape[1]} in {t_flow:.1f} s ({fc.method})", flush=True)
    summary: dict = {"footage": name, "method": fc.method, "temporal_sigma": float(fc.temporal_sigma),
                     "n_pairs": int(flow.shape[0]), "width": int(frames.shape[2]), "height": int(frames.shape[1]),
                     "time_s": t_flow, "mean_speed_px": float(np.linalg.norm(flow, axis=-1).mean())}
    # scoring: only now, and only if this is synthetic footage, is the truth read
    loaded = _load_truth(folder)
    truth = epe_frames = None
    if loaded is not None:
        truth, dye = loaded
        if truth.shape != flow.shape:
            raise ConfigError(f"{truth_path(folder)}: true velocity shape {truth.shape} does not match the flow {flow.shape}")
        epe_frames = np.array([endpoint_error(flow[i], truth[i]) for i in range(flow.shape[0])])
        base = estimate_flow(frames, method=fc.baseline, temporal_sigma=0.0)
        summary.update({"epe_px": float(epe_frames.mean()), "baseline": fc.baseline,
                        "epe_px_baseline": endpoint_error(base, truth),
                        "epe_px_no_temporal_smoothing": endpoint_error(estimate_flow(frames, method=fc.method), truth)
                        if fc.temporal_sigma > 0 else float(epe_frames.mean()),
                        "mean_speed_true_px": float(np.linalg.norm(truth, axis=-1).mean())})
        # where fluid is visible (dye > 0.5 at frame t): the only place texture can show motion
        vis = dye[:-1] > 0.5
        if vis.any():
            summary["epe_px_visible_fluid"] = endpoint_error(flow, truth, vis)
            summary["mean_speed_true_px_visible_fluid"] = float(np.linalg.norm(truth, axis=-1)[vis].mean())
            summary["visible_fluid_fraction"] = float(vis.mean())
        print(f"fluid_flow: {name}: EPE {summary['epe_px']:.3f} px ({fc.baseline}: {summary['epe_px_baseline']:.3f} px), "
              f"mean true speed {summary['mean_speed_true_px']:.3f} px/frame; "
              f"in visible fluid EPE {summary.get('epe_px_visible_fluid', float('nan')):.3f} px", flush=True)
    # about 40 arrows across at most: every 8 px on 1024-px footage was a solid mesh
    fig_step = max(4, int(fc.arrow_step), frames.shape[2] // 40)
    _figure(frames, flow, truth, out / "flow.png", f"{name}: optical flow ({fc.method})", fig_step)
    prog = Progress(flow.shape[0], f"fluid_flow {name} recording", enabled=cfg.log.progress)
    with make_logger(out / "flow.rrd", "vidsim.fluid_flow", cfg.log.rerun) as lg:
        for i in range(flow.shape[0]):
            lg.set_frame(i)
            lg.image("footage/camera/image", frames[i])
            o, v = arrow_grid(flow[i], int(fc.arrow_step), scale=2.0)
            lg.arrows2d("footage/camera/flow", o, v)
            if truth is not None:
                o, v = arrow_grid(truth[i], int(fc.arrow_step), scale=2.0)
                lg.arrows2d("truth/camera/velocity", o, v)
            prog.update()
        if epe_frames is not None:
            lg.series("metric/flow_epe_px", epe_frames, timeline="frame")
    # the main outputs last: a kill while the figure or recording is written leaves no new flow beside old figures
    write_text(out / "summary.csv", "quantity,value\n" + "".join(f"{k},{v}\n" for k, v in summary.items()))
    write_json(out / "summary.json", summary)
    write_npz(out / "flow.npz", flow=flow)


main = stage_app("fluid_flow", run)

if __name__ == "__main__":
    main()
