"""Real free flight: TrackLab ``verticalToss.webm`` through segmentation, tracking and flight fits.

Prints the detection rate and, per free flight, the RMS residual (pixels) of the weak-perspective
and the full-perspective fits, once with the container's timestamps and once at a constant 30 fps.

Usage::

    python benchmarks/bench_rigid_ball.py
"""

from __future__ import annotations

import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from vidsim.io.footage import read_video  # noqa: E402
from vidsim.io.paths import shared_data_dir  # noqa: E402
from vidsim.rigid.ballistic import fit_flight, fit_flight_perspective, split_flights, track_blob  # noqa: E402
from vidsim.video.segment import SegmentConfig, segment  # noqa: E402

BALL_SEG = SegmentConfig(min_area=4, open_px=0, close_px=1, mixed_fraction=0.0, clutter_fraction=0.1,
                         keep="all", max_area=600)


def main() -> None:
    cv2.setNumThreads(1)
    path = shared_data_dir() / "tracklab_physics" / "verticalToss.webm"
    frames, times = read_video(path)
    t = time.perf_counter()
    masks = segment(frames, cfg=BALL_SEG)
    centres, areas = track_blob(masks)
    secs = time.perf_counter() - t
    flights = split_flights(times, centres)
    first, last = flights[0][0], flights[-1][-1]
    found = np.isfinite(centres[first:last + 1, 0])
    dt = np.diff(times)
    print(f"{path.name}: {len(frames)} frames, container frame interval {1e3 * dt.min():.0f}-{1e3 * dt.max():.0f} ms "
          f"(median {1e3 * np.median(dt):.1f}); segmentation + tracking {secs:.1f} s")
    print(f"ball in free flight from frame {first} to {last}: found in {found.sum()}/{found.size} frames "
          f"({100 * found.mean():.1f} %); missing: {(np.flatnonzero(~found) + first).tolist()}")
    t30 = np.arange(len(times)) / 30.0
    for fl in flights:
        w_ts, w_30 = fit_flight(times, centres, fl), fit_flight(t30, centres, fl)
        p_ts = fit_flight_perspective(times, centres, areas, fl, (frames.shape[2], frames.shape[1]))
        p_30 = fit_flight_perspective(t30, centres, areas, fl, (frames.shape[2], frames.shape[1]))
        print(f"flight frames {fl[0]}-{fl[-1]} ({len(fl)}): RMS px weak-persp ts {w_ts.rms_px:.2f} / 30fps {w_30.rms_px:.2f}; "
              f"perspective ts {p_ts.rms_px:.2f} / 30fps {p_30.rms_px:.2f}; focal {p_ts.focal:.0f} px, depth "
              f"{p_ts.position[2]:.2f} m, ball radius {1e3 * p_ts.radius:.1f} mm, gravity (cam) "
              f"{np.round(p_ts.gravity / 9.81, 3).tolist()}")


if __name__ == "__main__":
    main()
