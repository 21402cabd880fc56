"""Ball-flight diagnosis: per-frame timing errors are named only when the footage has them."""

from __future__ import annotations

import numpy as np

from vidsim.gap.ball import diagnose_flights


def _flights(rng, jitter_s: float):
    f, cx, cy = 700.0, 319.5, 239.5
    tracks, areas, flights, times = [], [], [], []
    k0 = 0
    for X0, V0 in (([0.1, 0.5, 4.0], [0.2, -4.0, -0.8]), ([-0.2, 0.6, 3.5], [0.3, -3.6, 0.5]),
                   ([0.0, 0.4, 3.8], [-0.1, -3.8, 0.2])):
        n = 22
        t_nom = np.arange(n) / 30.0
        t_true = t_nom + rng.normal(0, jitter_s, n)
        P = np.asarray(X0) + np.outer(t_true, V0) + 0.5 * np.outer(t_true ** 2, [0, 9.81, 0])
        uv = np.stack([f * P[:, 0] / P[:, 2] + cx, f * P[:, 1] / P[:, 2] + cy], 1) + rng.normal(0, 0.3, (n, 2))
        tracks.append(uv)
        areas.append(np.pi * (f * 0.035 / P[:, 2]) ** 2)
        flights.append(np.arange(k0, k0 + n))
        times.append(t_nom + k0 / 30.0)
        k0 += n
    return np.concatenate(times), np.concatenate(tracks), np.concatenate(areas), flights


def test_planted_frame_time_jitter_is_named(rng):
    t, c, a, fl = _flights(rng, 0.004)
    d = diagnose_flights(t, c, a, fl, (640, 480))
    assert "time_jitter" in d["named"], d["jitter"]
    assert d["along_track_rms_px"] > 2 * d["cross_track_rms_px"]


def test_clean_flights_name_nothing(rng):
    t, c, a, fl = _flights(rng, 0.0)
    d = diagnose_flights(t, c, a, fl, (640, 480))
    assert d["named"] == [], d["jitter"]


def test_time_errors_carry_their_frames_when_a_short_flight_is_skipped(rng):
    """A flight with fewer than 8 detections is skipped: the time errors then belong to the other
    flights' frames, which the result names (gap_ball paired them with every flight's frames and
    its plot crashed on the length mismatch)."""
    t, c, a, fl = _flights(rng, 0.0)
    short = fl[1][:7]
    fl = [fl[0], short, fl[2]]
    d = diagnose_flights(t, c, a, fl, (640, 480))
    assert len(d["time_errors_s"]) == len(d["time_error_frames"]) == len(fl[0]) + len(fl[2])
    assert d["time_error_frames"] == [int(k) for k in np.r_[fl[0], fl[2]]]
    assert not set(d["time_error_frames"]) & set(short.tolist())
