"""Benchmark: angle map + gradient mask of one 320x240 striped frame (median of runs).

Run: ``.venv/bin/python benchmarks/bench_anglemap.py`` (single-threaded OpenCV).
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from vidsim.video.anglemap import SteerableBank, angle_map, energy_coefficients


def _median_ms(fn, runs: int) -> str:
    fn()  # warm-up (numba compile / cache load)
    ts = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return f"median {1e3 * float(np.median(ts)):.2f} ms (min {1e3 * float(np.min(ts)):.2f})"


def main(runs: int = 50) -> None:
    cv2.setNumThreads(1)
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:240, 0:320].astype(np.float32)
    img = 0.5 + 0.4 * np.sin(2 * np.pi * (yy + 0.2 * xx) / 8.0) + rng.normal(0, 0.05, yy.shape)
    img = img.astype(np.float32)
    bank = SteerableBank()
    resp = bank.responses(img)
    print(f"320x240, ksize={bank.ksize}, tuned period {bank.tuned_period_px:.1f} px, {runs} runs, 1 thread")
    print(f"  basis responses (7 separable filters): {_median_ms(lambda: bank.responses(img), runs)}")
    print(f"  coefficients C1..C3:                   {_median_ms(lambda: energy_coefficients(resp), runs)}")
    c = energy_coefficients(resp)
    sig = 0.5 * bank.tuned_period_px
    blur = lambda: [cv2.GaussianBlur(x, (0, 0), sig, borderType=cv2.BORDER_REFLECT) for x in c]  # noqa: E731
    print(f"  3 Gaussian blurs (sigma {sig:.1f} px):     {_median_ms(blur, runs)}")
    print(f"  full angle_map + mask(tau):            {_median_ms(lambda: angle_map(img, bank).mask(0.03), runs)}")


if __name__ == "__main__":
    main()
