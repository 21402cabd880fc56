"""Stage ``rigid_ball``: the real toss (TrackLab ``verticalToss.webm``) through segmentation and free-flight fits.

``python -m vidsim.cli.rigid_ball paths.out=results/rigid/ball`` (clip: ``rigid.paths.video`` or
``<shared data>/<rigid.ball.video>``). The same per-pixel background segmentation as the synthetic
throws finds the ball; a compact-blob tracker follows it; the track is split into free flights at
bounces; each flight is fitted by a parabola in the image (weak perspective) and by full
perspective free flight with unknown focal length (position, velocity, gravity direction in the
camera frame, scale from |g| = 9.81 m/s^2), once with the container's timestamps and once assuming
a constant ``rigid.ball.nominal_fps``. Writes ``ball.yaml``, ``ball.png`` and ``ball.rrd``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli._rigid import RigidStageError, ball_video, log_image, plain, segment_config
from vidsim.io.atomic import write_yaml
from vidsim.io.footage import read_video
from vidsim.log import make_logger
from vidsim.log.progress import Progress
from vidsim.report.figures import save_figure
from vidsim.rigid.ballistic import BallisticError, fit_flight, fit_flight_perspective, split_flights, track_blob
from vidsim.video.segment import segment

#: the stage warns below this many frames in flights or above this parabola (weak-perspective) fit RMS:
#: the real toss has 46 flight frames at 8.0-8.5 px; a clip with carts and no ball gave 6 frames at 44 px
BALL_MIN_FRAMES = 10
BALL_MAX_PARABOLA_RMS_PX = 20.0


def _plot(times, t_nom, centres, flights, fits, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(15, 4))
    k = np.arange(len(times))
    ax[0].plot(k, centres[:, 1], ".", ms=4, color="k", label="ball centroid (segmentation)")
    for i, (fl, f) in enumerate(zip(flights, fits)):
        tt = times[fl] - times[fl[0]]
        A = np.stack([np.ones_like(tt), tt, 0.5 * tt * tt], 1)
        ax[0].plot(fl, (A @ f["weak_ts"].coef)[:, 1], "-", color="tab:blue", label="parabola (timestamps)" if i == 0 else None)
        ax[1].plot(fl, np.linalg.norm(f["persp_ts"].residuals, axis=1), "o-", ms=3, color="tab:blue",
                   label="perspective, container timestamps" if i == 0 else None)
        ax[1].plot(fl, np.linalg.norm(f["persp_30"].residuals, axis=1), "s-", ms=3, color="tab:orange",
                   label="perspective, constant fps" if i == 0 else None)
    ax[0].invert_yaxis()
    ax[0].set_xlabel("frame")
    ax[0].set_ylabel("v (image row), px")
    ax[0].set_title("ball found and fitted per free flight")
    ax[0].legend(fontsize=8)
    ax[1].set_xlabel("frame")
    ax[1].set_ylabel("residual, px")
    ax[1].set_title("free-flight fit residuals")
    ax[1].legend(fontsize=8)
    ax[2].plot(k[1:], 1e3 * np.diff(times), ".-", ms=3, label="container timestamps")
    ax[2].plot(k[1:], 1e3 * np.diff(t_nom), "-", label="constant fps")
    ax[2].set_xlabel("frame")
    ax[2].set_ylabel("frame interval, ms")
    ax[2].set_title("timing")
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def run(cfg: DictConfig) -> None:
    b = cfg.rigid.ball
    video = ball_video(cfg, RigidStageError)
    if not b.nominal_fps > 0:
        raise RigidStageError(f"rigid.ball.nominal_fps = {b.nominal_fps} is not valid: expected > 0 Hz")
    out = Path(cfg.paths.out)
    prog = Progress(3, "rigid_ball", enabled=cfg.log.progress)
    frames, times = read_video(video)
    prog.update(note=f"{len(frames)} frames read")
    masks = segment(frames, cfg=segment_config(b.segment))
    centres, areas = track_blob(masks, b.min_area, b.max_area, b.min_fill, b.max_jump)
    prog.update(note="segmented and tracked")
    t_nom = np.arange(len(times)) / float(b.nominal_fps)
    flights = split_flights(times, centres, int(b.min_flight))
    if not flights:
        raise RigidStageError(f"{video}: no free flight of >= {b.min_flight} detections found (rigid.ball.*)")
    first, last = int(flights[0][0]), int(flights[-1][-1])
    found = np.isfinite(centres[first:last + 1, 0])
    size = (frames.shape[2], frames.shape[1])
    fits = []
    try:
        for fl in flights:
            fits.append({"weak_ts": fit_flight(times, centres, fl), "weak_30": fit_flight(t_nom, centres, fl),
                         "persp_ts": fit_flight_perspective(times, centres, areas, fl, size, b.focal_guess),
                         "persp_30": fit_flight_perspective(t_nom, centres, areas, fl, size, b.focal_guess)})
    except BallisticError as e:
        raise RigidStageError(f"{video}: {e}") from e
    prog.update(note=f"{len(flights)} flights fitted")

    def rms(key: str) -> float:  # over all flight frames together
        r = np.concatenate([f[key].residuals for f in fits])
        return float(np.sqrt((r ** 2).sum(1).mean()))

    dt = np.diff(times)
    doc = {
        "video": str(video), "n_frames": int(len(frames)),
        "frame_interval_ms": {"min": float(1e3 * dt.min()), "median": float(1e3 * np.median(dt)),
                              "max": float(1e3 * dt.max()), "nominal": 1e3 / float(b.nominal_fps)},
        "in_view": {"first_frame": first, "last_frame": last, "frames": int(found.size),
                    "found": int(found.sum()), "found_fraction": float(found.mean()),
                    "missing_frames": (np.flatnonzero(~found) + first).tolist()},
        "rms_px": {"perspective_timestamps": rms("persp_ts"), "perspective_constant_fps": rms("persp_30"),
                   "parabola_timestamps": rms("weak_ts"), "parabola_constant_fps": rms("weak_30")},
        "flights": [{"frames": [int(fl[0]), int(fl[-1])], "n": int(len(fl)),
                     **{k: f[k].summary() for k in ("weak_ts", "weak_30", "persp_ts", "persp_30")}}
                    for fl, f in zip(flights, fits)],
        "settings": plain(b),
    }
    for fd in doc["flights"]:
        for k in ("weak_ts", "weak_30", "persp_ts", "persp_30"):
            fd[k].pop("frames", None)
    _plot(times, t_nom, centres, flights, fits, out / "ball.png")
    with make_logger(out / "ball.rrd", "vidsim.rigid_ball", cfg.log.rerun) as lg:
        for i in range(len(frames)):
            lg.set_frame(i)
            log_image(lg, "footage/camera/image", frames[i])
            lg.mask("footage/camera/mask", masks[i])
            if np.isfinite(centres[i, 0]):
                lg.scalar("metric/ball_v_px", float(centres[i, 1]))
        for fl, f in zip(flights, fits):
            for j, k in enumerate(fl):
                lg.set_frame(int(k))
                lg.scalar("metric/residual_px_timestamps", float(np.linalg.norm(f["persp_ts"].residuals[j])))
                lg.scalar("metric/residual_px_constant_fps", float(np.linalg.norm(f["persp_30"].residuals[j])))
    r = doc["rms_px"]
    worst = max(r["parabola_timestamps"], r["parabola_constant_fps"])
    n_fit = int(sum(len(fl) for fl in flights))
    if not worst <= BALL_MAX_PARABOLA_RMS_PX or n_fit < BALL_MIN_FRAMES:
        # the blob tracked is not a ball in free flight (another moving object, or no ball at all): the
        # perspective fit has parameters enough to follow a few frames of anything, the parabola does not
        doc["warning"] = (f"the tracked blob may not be a ball in free flight ({n_fit} flight frames, parabola fit RMS "
                          f"{worst:.1f} px; expected >= {BALL_MIN_FRAMES} frames and <= {BALL_MAX_PARABOLA_RMS_PX} px): "
                          "check ball_sheet.png and rigid.ball.segment")
    write_yaml(out / "ball.yaml", doc)  # the main output last
    print(f"rigid_ball: ball found in {found.sum()}/{found.size} in-view frames ({100 * found.mean():.1f} %); "
          f"{len(flights)} flights; RMS px perspective {r['perspective_timestamps']:.2f} (timestamps) / "
          f"{r['perspective_constant_fps']:.2f} (constant {b.nominal_fps:g} fps), parabola "
          f"{r['parabola_timestamps']:.2f} / {r['parabola_constant_fps']:.2f}")
    if "warning" in doc:
        print(f"rigid_ball: warning: {doc['warning']}", file=sys.stderr)


main = stage_app("rigid_ball", run)

if __name__ == "__main__":
    main()
