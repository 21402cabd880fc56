"""Rendering throughput: fast numba rasteriser vs pyrender (EGL, Mesa llvmpipe).

Prints a table of frames per second (median of ``--runs`` runs, each rendering ``--frames``
frames of a ~3,000-triangle crumpled sheet in changing poses) for silhouette, depth and
colour+stripes renders at 320x240 and 640x480. Warm-up (numba compilation, first pyrender
render with shader compilation) is excluded. Single-threaded numba.

Usage::

    python benchmarks/bench_render.py [--runs 5] [--frames 20]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from vidsim.render import primitives as prim  # noqa: E402
from vidsim.render.projector import Projector, render_stripes, render_stripes_batch  # noqa: E402
from vidsim.render.raster import rasterize, silhouette, silhouette_batch  # noqa: E402
from vidsim.render.scene import MeshItem, Renderer, RenderFlags  # noqa: E402
from vidsim.video.camera import PinholeCamera, intrinsics, look_at  # noqa: E402


def sheet(n: int = 40, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Crumpled n x n sheet (2 (n-1)^2 triangles; n = 40 gives 3,042)."""
    rng = np.random.default_rng(seed)
    V, F = prim.grid_sheet(n, n, (0.6, 0.6))
    for _ in range(6):
        k = rng.normal(0, 9, 2)
        V[:, 2] += rng.uniform(0.01, 0.04) * np.sin(k[0] * V[:, 0] + k[1] * V[:, 1] + rng.uniform(0, 6.3))
    return V, F


def poses(V: np.ndarray, T: int, seed: int = 1) -> np.ndarray:
    """(T, N, 3) copies of V rotated about z and tilted, in front of the camera."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(T):
        a, b = rng.uniform(-0.6, 0.6, 2)
        Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        Rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
        out.append(V @ (Rx @ Rz).T + rng.uniform(-0.05, 0.05, 3))
    return np.stack(out)


def camera(w: int, h: int) -> PinholeCamera:
    R, t = look_at(np.array([0.2, -0.4, 1.3]), np.zeros(3), np.array([0.0, 1.0, 0.0]))
    return PinholeCamera(intrinsics(1.1 * w, None, (w - 1) / 2, (h - 1) / 2), R, t, w, h)


def projector() -> Projector:
    R, t = look_at(np.array([-0.3, -0.5, 1.2]), np.zeros(3), np.array([0.0, 1.0, 0.0]))
    return Projector(PinholeCamera(intrinsics(600.0, None, 255.5, 191.5), R, t, 512, 384), period_px=10.0)


def timed(fn, frames: int, runs: int) -> tuple[float, float]:
    """Median wall-clock frames per second of ``fn()`` (which renders ``frames`` frames) over ``runs``
    runs, and the median process CPU time per frame in ms (all threads, incl. llvmpipe's): on a
    shared machine the CPU time is the better guide to an unloaded one."""
    fn()  # warm-up: compilation / GL shader compile excluded
    ts, cs = [], []
    for _ in range(runs):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        ts.append(time.perf_counter() - t0)
        cs.append(time.process_time() - c0)
    return frames / statistics.median(ts), 1000.0 * statistics.median(cs) / frames


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--frames", type=int, default=20)
    a = ap.parse_args()
    V, F = sheet()
    Vs = poses(V, a.frames)
    proj = projector()
    print(f"mesh: {len(F)} triangles, {len(V)} vertices; projector {proj.cam.width}x{proj.cam.height}; "
          f"{a.frames} frames per run, median of {a.runs} runs; warm-up excluded")
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores (shared), "
          f"NUMBA_NUM_THREADS={os.environ['NUMBA_NUM_THREADS']}")
    rows = []
    rend = Renderer(320, 240)
    for w, h in ((320, 240), (640, 480)):
        cam = camera(w, h)
        items = [[MeshItem(v, F, color=(0.8, 0.8, 0.8))] for v in Vs]
        res = {
            ("silhouette", "fast"): timed(lambda: [silhouette(v, F, cam) for v in Vs], a.frames, a.runs),
            ("silhouette", "fast batch"): timed(lambda: silhouette_batch(Vs, F, cam), a.frames, a.runs),
            ("depth", "fast"): timed(lambda: [rasterize(v, F, cam) for v in Vs], a.frames, a.runs),
            ("depth+bary", "fast"): timed(lambda: [rasterize(v, F, cam, bary=True) for v in Vs], a.frames, a.runs),
            ("stripes", "fast"): timed(lambda: [render_stripes(v, F, cam, proj) for v in Vs], a.frames, a.runs),
            ("stripes", "fast batch"): timed(lambda: render_stripes_batch(Vs, F, cam, proj), a.frames, a.runs),
            ("silhouette+depth", "pyrender"): timed(
                lambda: [rend.render(it, cam, flags=RenderFlags.GEOMETRY_ONLY) for it in items], a.frames, a.runs),
            ("colour (lit)", "pyrender"): timed(lambda: [rend.render(it, cam) for it in items], a.frames, a.runs),
            ("colour+stripes", "pyrender"): timed(
                lambda: [rend.render(it, cam, projector=proj) for it in items], a.frames, a.runs),
        }
        for (what, backend), fps in res.items():
            rows.append((f"{w}x{h}", what, backend, fps))
    rend.close()
    # the cloth optimiser's budget: 50 frames of a 20x20-vertex swatch at 320x240, render + stripes
    Vc, Fc = sheet(20, seed=2)
    Vcs = poses(Vc, 50, seed=3)
    cam = camera(320, 240)
    fps, cpu = timed(lambda: render_stripes_batch(Vcs, Fc, cam, proj), 50, a.runs)
    rows.append(("320x240", f"stripes, {len(Fc)} tri", "fast batch", (fps, cpu)))
    print(f"cloth budget check: 50 frames of a 20x20-vertex swatch ({len(Fc)} triangles) at 320x240, "
          f"render + shadow map + stripes: {50 / fps * 1000:.1f} ms wall, {50 * cpu:.1f} ms CPU "
          f"(target well under 300 ms)")
    print(f"\n{'size':>8} | {'render':<17} | {'backend':<10} | {'frames/s':>9} | {'ms/frame':>8} | {'CPU ms/frame':>12}")
    print("-" * 81)
    for size, what, backend, (fps, cpu) in rows:
        print(f"{size:>8} | {what:<17} | {backend:<10} | {fps:9.1f} | {1000 / fps:8.2f} | {cpu:12.2f}")


if __name__ == "__main__":
    main()
