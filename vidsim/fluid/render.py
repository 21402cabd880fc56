"""Texture-transfer rendering of an edited velocity field (seed 5.4, PATCHSELECT).

Every output patch takes its colour from the source-video patch whose velocity
neighbourhood matches (K nearest neighbours in a KD-tree of velocity-patch features), chosen
among the K by data cost plus colour consistency with the already-filled output
(neighbourhood consistency). Overlapping patches are blended with linear feathering.

Sequence modes:

* ``"advected"``: patches are Lagrangian. Each frame a patch's output position moves with the
  edited field while its source window moves with the source flow and its source time
  advances, so the texture inside it moves like the edited field and keeps the source's own
  temporal texture dynamics. Holes opened by divergence are filled by new patches
  (PATCHSELECT against the current output, faded in); crowded cells and patches whose source
  clip ends fade out.
* ``"fixed"``: each output patch keeps its source window and plays the source forward in time
  (motion then equals the source motion at the matched patch).

Units: pixels and pixels per frame of the output; colours are float RGB in [0, 1] inside and
uint8 at the interface. Source clips shorter than 16 frames are used as still textures
(source time frozen) and only advected by the edited field.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable

import cv2
import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from vidsim.fluid.edit import RenderSettings


class RenderInputError(ValueError):
    """Inputs of the wrong shape or inconsistent sizes."""


@njit(cache=True)
def _feather(u: float, p: int, o: int) -> float:
    if u < -0.5 or u > p - 0.5:
        return 0.0
    if o <= 0:
        return 1.0
    a = min(u + 0.5, p - 0.5 - u) / o
    return min(max(a, 0.0), 1.0)


@njit(cache=True)
def _splat(frames, p, o, cx, cy, ts, sx, sy, alpha, acc, wsum, colour):
    """Accumulate patches: output top-left (cx, cy) float, source frame ts, source top-left
    (sx, sy) float, opacity alpha; bilinear sampling of the source."""
    T, hs, ws, _ = frames.shape
    ho, wo = wsum.shape
    for k in range(cx.shape[0]):
        if alpha[k] <= 0.0:
            continue
        ox = int(np.floor(cx[k]))
        oy = int(np.floor(cy[k]))
        fx = cx[k] - ox
        fy = cy[k] - oy
        t = ts[k]
        for a in range(p + 1):
            i = oy + a
            if i < 0 or i >= ho:
                continue
            v = a - fy
            wv = _feather(v, p, o)
            if wv == 0.0:
                continue
            ys = min(max(sy[k] + v, 0.0), hs - 1.000001)
            y0 = int(ys)
            gy = ys - y0
            for b in range(p + 1):
                j = ox + b
                if j < 0 or j >= wo:
                    continue
                u = b - fx
                wu = _feather(u, p, o)
                if wu == 0.0:
                    continue
                wgt = wu * wv * alpha[k]
                wsum[i, j] += wgt
                if not colour:
                    continue
                xs = min(max(sx[k] + u, 0.0), ws - 1.000001)
                x0 = int(xs)
                gx = xs - x0
                for c in range(3):
                    val = ((frames[t, y0, x0, c] * (1 - gx) + frames[t, y0, x0 + 1, c] * gx) * (1 - gy)
                           + (frames[t, y0 + 1, x0, c] * (1 - gx) + frames[t, y0 + 1, x0 + 1, c] * gx) * gy)
                    acc[i, j, c] += wgt * val


@njit(cache=True)
def _sample_flows(flows, ts, x, y):
    """Bilinear samples of ``flows[ts[k]]`` at (x[k], y[k]) (clamped): ``(K, 2)``."""
    _, h, w, _ = flows.shape
    out = np.empty((ts.shape[0], 2))
    for k in range(ts.shape[0]):
        cx = min(max(x[k], 0.0), w - 1.000001)
        cy = min(max(y[k], 0.0), h - 1.000001)
        j = int(cx)
        i = int(cy)
        gx = cx - j
        gy = cy - i
        f = flows[ts[k]]
        for c in range(2):
            out[k, c] = (f[i, j, c] * (1 - gx) + f[i, j + 1, c] * gx) * (1 - gy) + \
                (f[i + 1, j, c] * (1 - gx) + f[i + 1, j + 1, c] * gx) * gy
    return out


def _block_features(flow: np.ndarray, p: int) -> np.ndarray:
    """3x3 block means of a flow field for every patch top-left: ``(H-p+1, W-p+1, 18)``."""
    b = max(p // 3, 1)
    h, w, _ = flow.shape
    # bm[y, x] = mean of flow[y:y+b, x:x+b]
    c = np.pad(np.cumsum(np.cumsum(flow, 0), 1), ((1, 0), (1, 0), (0, 0)))
    bm = (c[b:, b:] - c[:-b, b:] - c[b:, :-b] + c[:-b, :-b]) / (b * b)
    hh, ww = h - p + 1, w - p + 1
    off = (p - 3 * b) // 2
    feats = [bm[off + i * b:off + i * b + hh, off + j * b:off + j * b + ww] for i in range(3) for j in range(3)]
    return np.concatenate(feats, axis=-1)


def _bilinear_field(f: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    h, w, _ = f.shape
    x = np.clip(x, 0, w - 1.000001)
    y = np.clip(y, 0, h - 1.000001)
    j = x.astype(int)
    i = y.astype(int)
    gx = (x - j)[:, None]
    gy = (y - i)[:, None]
    return (f[i, j] * (1 - gx) + f[i, j + 1] * gx) * (1 - gy) + (f[i + 1, j] * (1 - gx) + f[i + 1, j + 1] * gx) * gy


@dataclass
class _Patches:
    cx: np.ndarray
    cy: np.ndarray
    ts: np.ndarray
    sx: np.ndarray
    sy: np.ndarray
    alpha: np.ndarray
    dalpha: np.ndarray
    age: np.ndarray

    @classmethod
    def empty(cls) -> "_Patches":
        f = np.zeros(0)
        return cls(f, f.copy(), np.zeros(0, np.int64), f.copy(), f.copy(), f.copy(), f.copy(), np.zeros(0, np.int64))

    def append(self, cx, cy, ts, sx, sy, alpha, dalpha) -> None:
        self.cx = np.append(self.cx, cx)
        self.cy = np.append(self.cy, cy)
        self.ts = np.append(self.ts, np.int64(ts))
        self.sx = np.append(self.sx, sx)
        self.sy = np.append(self.sy, sy)
        self.alpha = np.append(self.alpha, alpha)
        self.dalpha = np.append(self.dalpha, dalpha)
        self.age = np.append(self.age, 0)

    def keep(self, m: np.ndarray) -> None:
        for k in ("cx", "cy", "ts", "sx", "sy", "alpha", "dalpha", "age"):
            setattr(self, k, getattr(self, k)[m])


class PatchSelector:
    """PATCHSELECT: KD-tree over source velocity-patch features and colour consistency."""

    def __init__(self, src: np.ndarray, src_flow: np.ndarray, p: int, k: int, min_life: int,
                 stride: int = 2, max_patches: int = 60000, color_weight: float = 4.0, seed: int = 0,
                 margin: int = 4, tolerance: float = 0.5) -> None:
        T = src.shape[0]
        self.tolerance = tolerance
        self.src, self.p, self.k, self.color_weight = src, p, k, color_weight
        last = max(T - 1 - min_life, 0) if T >= 16 else T - 1
        frames = np.arange(0, min(last, src_flow.shape[0] - 1) + 1)
        rng = np.random.default_rng(seed)
        self.rng = rng
        n_per = max_patches // max(len(frames), 1)
        feats, where = [], []
        for t in frames:
            # candidates keep ``margin`` px from the frame edge (inflow noise, flow artefacts)
            f = _block_features(src_flow[t], p)[margin:-margin or None:stride, margin:-margin or None:stride]
            yy, xx = np.mgrid[0:f.shape[0], 0:f.shape[1]] * stride + margin
            f = f.reshape(-1, 18)
            sel = rng.choice(len(f), min(n_per, len(f)), replace=False) if len(f) > n_per else np.arange(len(f))
            feats.append(f[sel])
            where.append(np.stack([np.full(len(sel), t), yy.ravel()[sel], xx.ravel()[sel]], 1))
        self.feats = np.concatenate(feats)
        self.where = np.concatenate(where)
        self.tree = cKDTree(self.feats)

    def select(self, feature: np.ndarray, existing: np.ndarray | None, mask: np.ndarray | None,
               coherent: list[tuple[int, int, int]] = (), src_flow: np.ndarray | None = None
               ) -> tuple[tuple[int, int, int], float]:
        """PATCHSELECT for one output patch.

        Candidates: the K nearest velocity patches of the video, plus "coherent" candidates
        (the source windows that continue already placed overlapping patches, as in
        Ashikhmin's coherent synthesis). Cost = data (mean squared velocity-feature distance,
        px^2/frame^2) + ``color_weight`` * mean squared colour difference over the overlap
        with the already filled output (neighbourhood consistency).

        Returns:
            the chosen source ``(t, y, x)`` and its data cost.
        """
        d, idx = self.tree.query(feature, k=self.k, eps=0.5)
        cands = [tuple(int(a) for a in self.where[i]) for i in np.atleast_1d(idx)]
        data = list(np.atleast_1d(d) ** 2 / 18.0)
        p = self.p
        T, hs, ws = self.src.shape[:3]
        for t, y, x in coherent:
            if 0 <= t < T and 0 <= y <= hs - p and 0 <= x <= ws - p and src_flow is not None:
                f = _block_features(src_flow[t, y:y + p, x:x + p], p)[0, 0]
                cands.append((t, y, x))
                data.append(float(((f - feature) ** 2).sum() / 18.0))
        e = np.array(data, dtype=np.float64)
        if existing is not None and mask is not None and mask.sum() > 0:
            for n, (t, y, x) in enumerate(cands):
                cand = self.src[t, y:y + p, x:x + p]
                diff = (cand - existing) ** 2
                e[n] += self.color_weight * float((diff.sum(-1) * mask).sum() / (3 * mask.sum()))
        # diversity: draw among candidates within ``tolerance`` of the best cost, so that a
        # uniform field does not repeat one source patch (texture-by-numbers "pick among good")
        good = np.flatnonzero(e <= e.min() * (1.0 + self.tolerance) + 1e-12)
        best = int(self.rng.choice(good))
        return cands[best], float(data[best])


def render_sequence(src_frames: np.ndarray, src_flow: np.ndarray, edited_field: np.ndarray, n_frames: int,
                    rng: np.random.Generator, settings: RenderSettings | None = None,
                    solid: np.ndarray | None = None, color_weight: float = 0.1,
                    match_flow: np.ndarray | None = None,
                    on_frame: Callable[[int], None] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
    """Render ``n_frames`` of the edited field by texture transfer from the source video.

    Args:
        src_frames: ``(T, Hs, Ws, 3)`` uint8 source video.
        src_flow: ``(T-1, Hs, Ws, 2)`` its optical flow (px/frame), e.g. :func:`estimate_flow`.
        edited_field: ``(H, W, 2)`` edited velocity (px/frame at output resolution), or
            ``(n_frames, H, W, 2)`` one field per output frame.
        n_frames: output frames.
        rng: random generator (seeds the candidate subsampling).
        settings: patch size, overlap, K, mode; defaults of :class:`RenderSettings`.
        solid: optional ``(H, W)`` obstacle mask of the output (patches are not spawned
            centred inside it; they still get colour there from zero-velocity source patches).
        on_frame: optional callback ``on_frame(n)`` after output frame ``n`` (progress lines).

    Returns:
        ``(n_frames, H, W, 3)`` uint8 frames and figures: ``time_per_frame_s``,
        ``patches_mean``, ``spawned``, ``data_cost_mean`` (mean squared velocity-feature
        distance of the chosen patches, px^2/frame^2).
    """
    s = settings or RenderSettings()
    src_frames = np.asarray(src_frames)
    if src_frames.ndim != 4 or src_frames.shape[-1] != 3 or src_frames.dtype != np.uint8:
        raise RenderInputError(f"src_frames shape {src_frames.shape} dtype {src_frames.dtype}, expected (T,H,W,3) uint8")
    T = src_frames.shape[0]
    if src_flow.shape != (T - 1, *src_frames.shape[1:3], 2):
        raise RenderInputError(f"src_flow shape {src_flow.shape}, expected {(T - 1, *src_frames.shape[1:3], 2)}")
    ef = np.asarray(edited_field, dtype=np.float64)
    if ef.ndim == 3:
        ef = ef[None]
    if ef.ndim != 4 or ef.shape[-1] != 2 or ef.shape[0] not in (1, n_frames):
        raise RenderInputError(f"edited_field shape {np.shape(edited_field)}, expected (H,W,2) or ({n_frames},H,W,2)")
    if n_frames < 1:
        raise RenderInputError(f"n_frames={n_frames}, expected >= 1")
    H, W = ef.shape[1:3]
    p, o = s.patch, s.overlap
    if H < p or W < p or src_frames.shape[1] < p or src_frames.shape[2] < p:
        raise RenderInputError(f"patch={p} larger than the output {W}x{H} or the source")
    temporal = T >= 16
    fade = 6
    min_life = min(24, max(T // 3, 1))
    src = src_frames.astype(np.float32) / 255.0
    sflow = np.asarray(src_flow, dtype=np.float64)
    if sflow.shape[0] < T:
        sflow = np.concatenate([sflow, sflow[-1:]], 0)  # flow of the last frame: reuse
    if match_flow is None:
        mflow = sflow
    else:
        mflow = np.asarray(match_flow, dtype=np.float64)
        if mflow.ndim == 3:
            mflow = np.broadcast_to(mflow, sflow.shape)
        elif mflow.shape[0] == T - 1:
            mflow = np.concatenate([mflow, mflow[-1:]], 0)
        if mflow.shape != sflow.shape:
            raise RenderInputError(f"match_flow shape {np.shape(match_flow)} does not fit src_flow {src_flow.shape}")
    sel = PatchSelector(src, mflow, p, s.k, min_life, seed=int(rng.integers(1 << 31)), color_weight=color_weight)
    step = p - o
    grid_y = np.unique(np.r_[np.arange(0, H - p + 1, step), H - p])
    grid_x = np.unique(np.r_[np.arange(0, W - p + 1, step), W - p])
    advect = s.mode == "advected"
    P = _Patches.empty()
    out = np.empty((n_frames, H, W, 3), np.uint8)
    spawned = 0
    costs: list[float] = []
    n_live: list[int] = []
    t0 = time.perf_counter()

    def spawn(cx: int, cy: int, field: np.ndarray, acc: np.ndarray, wsum: np.ndarray, alpha: float) -> None:
        nonlocal spawned
        feat = _block_features(field[cy:cy + p, cx:cx + p], p)[0, 0]
        w = wsum[cy:cy + p, cx:cx + p]
        mask = (w > 0.05).astype(np.float64)
        existing = acc[cy:cy + p, cx:cx + p] / np.maximum(w, 1e-9)[..., None]
        near = np.flatnonzero((np.abs(P.cx - cx) < p - o) & (np.abs(P.cy - cy) < p - o) & (P.alpha > 0.5))
        coh = [(int(P.ts[j]), int(round(P.sy[j] + cy - P.cy[j])), int(round(P.sx[j] + cx - P.cx[j]))) for j in near[-4:]]
        (t, y, x), c = sel.select(feat, existing, mask, coh, mflow)
        P.append(cx, cy, t, x, y, alpha, 1.0 / fade if alpha < 1 else 0.0)
        _splat(src, p, o, P.cx[-1:], P.cy[-1:], P.ts[-1:], P.sx[-1:], P.sy[-1:], P.alpha[-1:], acc, wsum, True)
        spawned += 1
        costs.append(c)

    for n in range(n_frames):
        field = ef[min(n, ef.shape[0] - 1)]
        if n > 0 and len(P.cx):
            if advect:
                v = _bilinear_field(field, P.cx + p / 2, P.cy + p / 2)
                P.cx = P.cx + v[:, 0]
                P.cy = P.cy + v[:, 1]
            if temporal:
                if advect:
                    vs = _sample_flows(sflow, P.ts, P.sx + p / 2, P.sy + p / 2)
                    P.sx = P.sx + vs[:, 0]
                    P.sy = P.sy + vs[:, 1]
                P.ts = np.minimum(P.ts + 1, T - 1)
            P.age += 1
            P.alpha = np.clip(P.alpha + P.dalpha, 0.0, 1.0)
            P.dalpha[(P.alpha >= 1.0) & (P.dalpha > 0)] = 0.0
            # retire: source clip ending, crowding, outside the frame
            if temporal:
                P.dalpha[(P.ts >= T - 1 - fade) & (P.dalpha >= 0)] = -1.0 / fade
            # source window drifting off the source frame: retire (clamped samples would streak)
            hs, ws = src.shape[1:3]
            off = (P.sx < 0) | (P.sy < 0) | (P.sx > ws - p) | (P.sy > hs - p)
            P.dalpha[off & (P.dalpha >= 0)] = -1.0 / fade
            P.sx = np.clip(P.sx, 0, ws - p)
            P.sy = np.clip(P.sy, 0, hs - p)
            ccx, ccy = P.cx + p / 2, P.cy + p / 2
            inside = (ccx > -p / 4) & (ccx < W + p / 4) & (ccy > -p / 4) & (ccy < H + p / 4)
            P.keep(inside & ((P.alpha > 0) | (P.dalpha > 0)))
            if advect and len(P.cx):
                cell = (np.clip(P.cy + p / 2, 0, H - 1) // step).astype(int) * 100000 + \
                    (np.clip(P.cx + p / 2, 0, W - 1) // step).astype(int)
                order = np.lexsort((-P.age, cell))
                cs = cell[order]
                first = np.r_[True, cs[1:] != cs[:-1]]
                rank = np.arange(len(cs)) - np.maximum.accumulate(np.where(first, np.arange(len(cs)), 0))
                crowded = order[rank >= 2]
                P.dalpha[crowded] = np.minimum(P.dalpha[crowded], -1.0 / fade)
        acc = np.zeros((H, W, 3))
        wsum = np.zeros((H, W))
        if len(P.cx):
            _splat(src, p, o, P.cx, P.cy, P.ts, P.sx, P.sy, P.alpha, acc, wsum, True)
        # fill holes (all of frame 0) in raster order
        for gy in grid_y:
            for gx in grid_x:
                cov = wsum[gy + o:gy + p - o, gx + o:gx + p - o]
                if cov.size and cov.mean() < 0.9:
                    if solid is not None and n > 0 and solid[gy + p // 2, gx + p // 2] and cov.mean() > 0.2:
                        continue
                    spawn(int(gx), int(gy), field, acc, wsum, 1.0 if n == 0 else 0.35)
        img = acc / np.maximum(wsum, 1e-9)[..., None]
        out[n] = np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)
        n_live.append(len(P.cx))
        if on_frame is not None:
            on_frame(n)
    dt = time.perf_counter() - t0
    figs = {"time_per_frame_s": dt / n_frames, "patches_mean": float(np.mean(n_live)), "spawned": spawned,
            "data_cost_mean": float(np.mean(costs)) if costs else 0.0, "mode": s.mode,
            "source_temporal": temporal, "source_candidates": len(sel.feats)}
    return out, figs


def upsample_field(field: np.ndarray, factor: int, size: tuple[int, int] | None = None) -> np.ndarray:
    """Edit-grid field (nodes/frame) to output pixels (px/frame): resize by ``factor`` and
    multiply the vectors by ``factor``. ``size`` = (H, W) overrides the output size."""
    h, w = field.shape[:2]
    H, W = size if size is not None else (h * factor, w * factor)
    up = cv2.resize(field.astype(np.float32), (W, H), interpolation=cv2.INTER_LINEAR)
    return up.astype(np.float64) * factor


def downsample_flow(flow: np.ndarray, factor: int) -> np.ndarray:
    """Flow ``(..., H, W, 2)`` px/frame to a grid ``factor`` times coarser (nodes/frame):
    block mean divided by ``factor`` (H and W are cropped to multiples of ``factor``)."""
    f = np.asarray(flow, dtype=np.float64)
    H, W = f.shape[-3] // factor * factor, f.shape[-2] // factor * factor
    f = f[..., :H, :W, :]
    sh = f.shape[:-3] + (H // factor, factor, W // factor, factor, 2)
    return f.reshape(sh).mean(axis=(-4, -2)) / factor
