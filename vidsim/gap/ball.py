"""Gap diagnosis of a tracked ball's free flights (the real toss): is frame timing the missing effect?

Model per flight: full-perspective free flight with unknown focal length
(:func:`vidsim.rigid.ballistic.fit_flight_perspective`); the gap is its centroid residual, linearised
at the fit (base Jacobian by central differences). Candidates, additive with 0 = off:

* ``time_jitter``: one time error per frame, ``c(t_k + d_k)``: column ``dc/dt(t_k)`` on frame k;
* ``linear_drag``: ``X -= k (V0 t^2 / 2 + g t^3 / 6)`` (first order in the drag rate k, 1/s);
* ``time_rate``: ``t -> t (1 + r)``, nearly absorbed by the free velocity and gravity direction;

and a *placebo* for the jitter: one shift per frame *across* the track (same count, same size,
no timing meaning). Frame timing can only move the ball along its track, so the evidence for
jitter is what the along-track freedom explains beyond the placebo. Drag is judged on the other
flights (leave one flight out: its rate fitted on the others, the held-out flight's own
state refitted).
"""

from __future__ import annotations

import numpy as np

from vidsim.gap.rigid_diagnose import _white_fraction, score_screen
from vidsim.gap.rigid_model import GapError


def _persp_track(theta: np.ndarray, t: np.ndarray, cxy: tuple[float, float], k_drag: float = 0.0) -> np.ndarray:
    """(n, 2) image track of ``theta = [X0 (3), V0 (3), g (3), log f]`` with linear drag rate ``k``."""
    X0, V0, g, f = theta[0:3], theta[3:6], theta[6:9], np.exp(theta[9])
    P = (X0 + np.outer(t, V0) + 0.5 * np.outer(t * t, g)
         - k_drag * (0.5 * np.outer(t * t, V0) + np.outer(t ** 3 / 6.0, g)))
    z = np.maximum(P[:, 2], 1e-3)
    return np.stack([f * P[:, 0] / z + cxy[0], f * P[:, 1] / z + cxy[1]], 1)


def _flat(c: np.ndarray) -> np.ndarray:
    return np.r_[c[:, 0], c[:, 1]]


def _jac(fun, theta: np.ndarray, steps: np.ndarray) -> np.ndarray:
    cols = []
    for j, h in enumerate(steps):
        tp = theta.copy()
        tp[j] += h
        tm = theta.copy()
        tm[j] -= h
        cols.append((_flat(fun(tp)) - _flat(fun(tm))) / (2 * h))
    return np.stack(cols, 1)


def diagnose_flights(times: np.ndarray, centres: np.ndarray, areas: np.ndarray, flights: list[np.ndarray],
                     image_size: tuple[int, int], min_share: float = 0.3, min_white: float = 0.5,
                     prior_s: float = 0.01) -> dict:
    """Diagnose the parabola fits of tracked flights under one reading of the frame times.

    Args:
        times: (T,) frame times of this reading, seconds.
        centres: (T, 2) ball centroids, pixels (NaN where not found); areas: (T,) blob areas, px.
        flights: frame indices of each free flight (:func:`vidsim.rigid.ballistic.split_flights`).
        image_size: (width, height), pixels.
        min_share: share of the residual sum of squares an effect must explain beyond its
            placebo (jitter) or on held-out flights (drag) to be named.
        min_white: share of the fitted time errors' variance a cubic drift must leave (jitter).
        prior_s: prior std of a frame's time error, seconds (and of the placebo's equal shift).

    Returns:
        JSON-friendly dictionary: ``rms_px``, ``along_track_rms_px``, ``cross_track_rms_px``,
        ``screen`` (fractions), ``jitter`` (beyond-placebo share, fitted std, whiteness),
        ``drag`` (held-out share per flight), ``named`` and ``verdict``.
    """
    times = np.asarray(times, float)
    centres = np.asarray(centres, float)
    if centres.shape != (len(times), 2):
        raise GapError(f"centres must be (T, 2) with T = len(times) = {len(times)}, got {centres.shape}")
    if not flights:
        raise GapError("no free flight to diagnose")
    sse = sse_jit = sse_plc = 0.0
    along, cross, dks, tks = [], [], [], []
    screens = []
    per_flight = []
    from vidsim.rigid.ballistic import fit_flight_perspective

    for fl in flights:
        fl = np.asarray(fl, int)
        fl = fl[np.isfinite(centres[fl, 0])]
        if len(fl) < 8:
            continue
        pf = fit_flight_perspective(times, centres, areas, fl, image_size)
        t = times[fl] - times[fl[0]]
        c = centres[fl]
        n = len(t)
        cxy = ((image_size[0] - 1) / 2.0, (image_size[1] - 1) / 2.0)
        theta = np.r_[pf.position, pf.velocity, pf.gravity, np.log(pf.focal)]
        track = _persp_track(theta, t, cxy)
        r = _flat(track - c)
        # base Jacobian (gravity as a free 3-vector: |g| is fixed in the fit, so this over-counts
        # one direction, which only makes the screen more conservative)
        steps = np.r_[np.full(3, 1e-3 * max(abs(pf.position[2]), 0.1)), np.full(3, 1e-3 * max(np.linalg.norm(pf.velocity), 0.1)),
                      np.full(3, 1e-2), 1e-3]
        J0 = _jac(lambda th: _persp_track(th, t, cxy), theta, steps)
        vel = np.gradient(track, t, axis=0)
        sp = np.linalg.norm(vel, axis=1)
        u = vel / np.maximum(sp, 1e-9)[:, None]
        R = track - c
        along.append((R * u).sum(1))
        cross.append(R[:, 0] * -u[:, 1] + R[:, 1] * u[:, 0])
        Jj = np.zeros((2 * n, n))
        Jp = np.zeros((2 * n, n))
        for k in range(n):
            Jj[k, k], Jj[n + k, k] = vel[k]
            Jp[k, k], Jp[n + k, k] = -vel[k, 1], vel[k, 0]
        Jd = ((_flat(_persp_track(theta, t, cxy, 1e-3)) - _flat(track)) / 1e-3)[:, None]
        Jr = _flat(vel * t[:, None])[:, None]
        scr = score_screen(J0, {"time_jitter": Jj, "placebo_jitter": Jp, "linear_drag": Jd, "time_rate": Jr}, r)
        screens.append(scr)
        # per-frame refits (linearised at the perspective fit, base parameters free): one time
        # error per frame, or one placebo shift per frame across the track
        # MAP with a Gaussian prior of std ``prior_s`` on each time error (and on each placebo
        # shift of the same image size); noise variance from the cross-track residual
        sig2 = max(float(np.mean(cross[-1] ** 2)), 1e-6)
        for Jx, key in ((Jj, "jit"), (Jp, "plc")):
            A = np.concatenate([J0, Jx], 1)
            reg = np.diag(np.r_[np.zeros(J0.shape[1]), np.full(n, sig2 / prior_s ** 2)])
            z = np.linalg.solve(A.T @ A + reg + 1e-12 * np.eye(A.shape[1]), -A.T @ r)
            rr = r + A @ z
            if key == "jit":
                sse_jit += float(rr @ rr)
                dks.append(z[J0.shape[1]:])
                tks.append(t)
            else:
                sse_plc += float(rr @ rr)
        # drag refit on this flight alone (linearised), kept for the leave-one-out check
        A = np.concatenate([J0, Jd], 1)
        sse += float(r @ r)
        per_flight.append({"frames": [int(fl[0]), int(fl[-1])], "n": n, "rms_px": float(np.sqrt((R ** 2).sum(1).mean())),
                           "J0": J0, "Jd": Jd[:, 0], "r": r, "idx": fl})
    if not per_flight:
        raise GapError("no flight with >= 8 detections")
    # drag: leave one flight out (rate from the other flights, the held-out flight's own base refitted)
    drag = []
    if len(per_flight) >= 2:
        for i, f in enumerate(per_flight):
            num = den = 0.0
            for j, o in enumerate(per_flight):
                if j == i:
                    continue
                P = o["Jd"] - o["J0"] @ np.linalg.lstsq(o["J0"], o["Jd"], rcond=None)[0]
                num += float(P @ o["r"])
                den += float(P @ P)
            k_hat = -num / den if den > 0 else 0.0
            y = f["r"] + f["Jd"] * k_hat
            rr = y - f["J0"] @ np.linalg.lstsq(f["J0"], y, rcond=None)[0]
            r0 = f["r"] - f["J0"] @ np.linalg.lstsq(f["J0"], f["r"], rcond=None)[0]
            share = float(1.0 - (rr @ rr) / max(r0 @ r0, 1e-12))
            # k_per_s is the rate the other flights imply; where it does not help the held-out flight
            # (share <= 0) it is not identified, and its value (thousands of 1/s on the real toss) means nothing
            drag.append({"flight": f["frames"], "k_per_s": k_hat, "heldout_share": share, "identified": share > 0})
    share_jit = (sse - sse_jit) / sse if sse > 0 else 0.0
    share_plc = (sse - sse_plc) / sse if sse > 0 else 0.0
    dk = np.concatenate(dks) if dks else np.zeros(0)
    white = float(np.mean([_white_fraction(tt, d) for tt, d in zip(tks, dks)])) if dks else 0.0
    beyond = share_jit - share_plc
    named = []
    if beyond >= min_share and white >= min_white:
        named.append("time_jitter")
    if drag and np.median([d["heldout_share"] for d in drag]) >= min_share:
        named.append("linear_drag")
    al = np.concatenate(along)
    cr = np.concatenate(cross)
    screen = {k: float(np.mean([s[k]["fraction"] for s in screens])) for k in screens[0]}
    return {
        "rms_px": float(np.sqrt((al ** 2 + cr ** 2).mean())),
        "along_track_rms_px": float(np.sqrt((al ** 2).mean())),
        "cross_track_rms_px": float(np.sqrt((cr ** 2).mean())),
        "screen": screen,
        "jitter": {"share_explained": share_jit, "placebo_share": share_plc, "beyond_placebo": beyond,
                   "fitted_std_ms": float(1e3 * np.std(dk)), "white_fraction": white},
        "drag": drag,
        "flights": [{k: v for k, v in f.items() if k in ("frames", "n", "rms_px")} for f in per_flight],
        "named": named,
        "verdict": ("explained by " + ", ".join(named)) if named else "none of the candidates explains the residual",
        "time_errors_s": dk.tolist(),
        # the frame of each time error: the frames of the flights diagnosed (a flight with fewer than
        # 8 detections is skipped, so these can be fewer than the flights' frames)
        "time_error_frames": [int(k) for f in per_flight for k in f["idx"]],
    }
