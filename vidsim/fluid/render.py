"""Texture-transfer rendering of an edited velocity field (seed 5.4, PATCHSELECT).

Every output patch takes its colour from a source-video patch whose velocity neighbourhood
matches (:class:`PatchSelector`): candidates are the K nearest velocity patches (KD-tree of
velocity-patch features) plus K drawn at random among all patches that match within the
flow's accuracy; the velocity match keeps the ones as good as the best, and among those
colour consistency with the already-filled output (neighbourhood consistency, in a form
without L2's bias towards low-contrast patches) and uniform use of the source decide.
Overlapping patches are blended by linear feathering, by a correlation-aware
variance-preserving blend or by a two-band blend that feathers the coarse band and takes the
fine band from one patch per pixel (:func:`_compose`); sub-pixel source positions are sampled
bicubically.

Sequence modes:

* ``"advected"``: patches are Lagrangian. Each frame a patch's output position moves with the
  edited field while its source window moves with the source flow and its source time
  advances, so the texture inside it moves like the edited field and keeps the source's own
  temporal texture dynamics. Holes opened by divergence are filled by new patches
  (PATCHSELECT against the current output, faded in; no pixel outside the obstacles' fills is
  left uncovered); crowded cells and patches whose source clip ends fade out. Patches centred
  on an obstacle (``solid``) hold their source frame.

Obstacles that are in the footage at the same place (``footage_solid``, e.g. a PIV recording's
cylinder) show the footage's own pixels: the per-pixel temporal median of the source, blended
into the synthesised fluid over ``overlap`` px outside the obstacle's edge (:func:`obstacle_alpha`).
No fluid patch takes texture from what that fill shows: the candidates touching it are left out
of the fluid's pool, and a patch whose source window would drift onto it stops there and fades
out. Obstacles the edit
adds (``transplants``) show the same median image of one of the footage's obstacles, mapped onto
their shape (:class:`Transplant`) and blended like the fill, and no patch is spawned centred in
them; without ``transplants`` they take their texture from windows centred in the footage's
obstacles (solid texture).
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
def _catmull_rom(g: float, w: np.ndarray) -> None:
    """Catmull-Rom (Keys a = -1/2) weights of the taps at -1, 0, 1, 2 for fraction ``g``."""
    g2 = g * g
    g3 = g2 * g
    w[0] = 0.5 * (-g3 + 2.0 * g2 - g)
    w[1] = 0.5 * (3.0 * g3 - 5.0 * g2 + 2.0)
    w[2] = 0.5 * (-3.0 * g3 + 4.0 * g2 + g)
    w[3] = 0.5 * (g3 - g2)


@njit(cache=True)
def _sample(frames, t, y0, x0, gy, gx, wy, wx, c, cubic):
    """Channel ``c`` of ``frames[t]`` at (y0 + gy, x0 + gx): Catmull-Rom (weights ``wy``, ``wx``
    already set for gy, gx) if ``cubic``, else bilinear; taps clamped to the frame."""
    hs, ws = frames.shape[1:3]
    if cubic:
        val = 0.0
        for dy in range(4):
            yy = min(max(y0 - 1 + dy, 0), hs - 1)
            row = 0.0
            for dx in range(4):
                xx = min(max(x0 - 1 + dx, 0), ws - 1)
                row += wx[dx] * frames[t, yy, xx, c]
            val += wy[dy] * row
        return val
    return ((frames[t, y0, x0, c] * (1 - gx) + frames[t, y0, x0 + 1, c] * gx) * (1 - gy)
            + (frames[t, y0 + 1, x0, c] * (1 - gx) + frames[t, y0 + 1, x0 + 1, c] * gx) * gy)


# channels of the splat accumulator (per output pixel)
_ACC, _MEAN, _W, _W2, _OFF, _OFF2 = slice(0, 3), slice(3, 6), 6, 7, slice(8, 11), 11
_FINE, _WMAX, _OWN = slice(12, 15), 15, slice(16, 19)
_N_ACC = 19
# the multi-band blend's fine band: the source minus its Gaussian blur of this x overlap px
BAND_SIGMA_PER_OVERLAP = 0.5


@njit(cache=True)
def _splat(frames, p, o, cx, cy, ts, sx, sy, alpha, frame, accum, colour, cubic, fine):
    """Accumulate patches: output top-left (cx, cy) float, source frame ts, source top-left
    (sx, sy) float, opacity alpha, at output frame ``frame``. ``accum`` (H, W, 19) sums per
    output pixel: weight x colour, weight x the patch's mean colour, weight, squared weight,
    weight x the patch's source offset (sx - cx, sy - cy, p (ts - frame)) and weight x its
    squared norm (for :func:`_compose`); with ``fine`` (the source frames' fine band,
    :func:`fine_band`; any array of another shape: none) also weight x the fine band, and the
    largest weight at the pixel with the fine band of the patch that has it (its owner; on
    ties the earlier patch, i.e. the older). The source is sampled bicubically (Catmull-Rom)
    if ``cubic``, else bilinearly."""
    T, hs, ws, _ = frames.shape
    ho, wo = accum.shape[:2]
    bands = fine.shape == frames.shape
    n = p + 1
    buf = np.zeros((n, n, 3))
    fbuf = np.zeros((n, n, 3))
    wb = np.zeros((n, n))
    wy = np.zeros(4)
    wx = np.zeros(4)
    for k in range(cx.shape[0]):
        if alpha[k] <= 0.0:
            continue
        ox = int(np.floor(cx[k]))
        oy = int(np.floor(cy[k]))
        fx = cx[k] - ox
        fy = cy[k] - oy
        t = ts[k]
        off0 = sx[k] - cx[k]
        off1 = sy[k] - cy[k]
        off2 = p * (t - frame)
        msum = np.zeros(3)
        mw = 0.0
        for a in range(n):
            v = a - fy
            wv = _feather(v, p, o)
            ys = min(max(sy[k] + v, 0.0), hs - 1.000001)
            y0 = int(ys)
            gy = ys - y0
            _catmull_rom(gy, wy)
            for b in range(n):
                wb[a, b] = 0.0
                i = oy + a
                j = ox + b
                if wv == 0.0 or i < 0 or i >= ho or j < 0 or j >= wo:
                    continue
                u = b - fx
                wu = _feather(u, p, o)
                if wu == 0.0:
                    continue
                wb[a, b] = wu * wv * alpha[k]
                if not colour:
                    continue
                xs = min(max(sx[k] + u, 0.0), ws - 1.000001)
                x0 = int(xs)
                gx = xs - x0
                if cubic:
                    _catmull_rom(gx, wx)
                for c in range(3):
                    buf[a, b, c] = _sample(frames, t, y0, x0, gy, gx, wy, wx, c, cubic)
                    msum[c] += buf[a, b, c]
                    if bands:
                        fbuf[a, b, c] = _sample(fine, t, y0, x0, gy, gx, wy, wx, c, cubic)
                mw += 1.0
        for a in range(n):
            for b in range(n):
                wgt = wb[a, b]
                if wgt == 0.0:
                    continue
                i = oy + a
                j = ox + b
                accum[i, j, 6] += wgt
                accum[i, j, 7] += wgt * wgt
                if colour:
                    for c in range(3):
                        accum[i, j, c] += wgt * buf[a, b, c]
                        accum[i, j, 3 + c] += wgt * msum[c] / mw
                    accum[i, j, 8] += wgt * off0
                    accum[i, j, 9] += wgt * off1
                    accum[i, j, 10] += wgt * off2
                    accum[i, j, 11] += wgt * (off0 * off0 + off1 * off1 + off2 * off2)
                    if bands:
                        owner = wgt > accum[i, j, 15]
                        if owner:
                            accum[i, j, 15] = wgt
                        for c in range(3):
                            accum[i, j, 12 + c] += wgt * fbuf[a, b, c]
                            if owner:
                                accum[i, j, 16 + c] = fbuf[a, b, c]


def fine_band(frames: np.ndarray, sigma: float) -> np.ndarray:
    """The fine band of float frames ``(T, H, W, C)``: each frame minus its Gaussian blur of
    ``sigma`` px (border reflected)."""
    out = np.empty_like(frames)
    for t in range(len(frames)):
        out[t] = frames[t] - cv2.GaussianBlur(frames[t], (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    return out


def _compose(accum: np.ndarray, preserve: bool, corr_len: float, bands: bool = False) -> np.ndarray:
    """Blend the splatted patches.

    Multi-band (``bands``; Burt & Adelson 1983, as Brown & Lowe 2007 stitch panoramas): the
    coarse band (colour minus :func:`fine_band`) blended linearly, the fine band that of the
    pixel's owner alone (the patch of largest weight there, :func:`_splat`): the hard partition
    a Laplacian pyramid's finest level is blended with. Linear feathering averages the fine
    texture of overlapping unrelated patches, dividing its contrast by up to ``sqrt(n)``; this
    shows one patch's own texture at every pixel, and the feather still hides the seams'
    coarse steps.

    Linear (``preserve`` False): the weighted mean, i.e. feathering. Variance-preserving
    (Heitz & Neyret 2018, made correlation-aware): ``mu + (L - mu) g`` with ``L`` the weighted
    mean, ``mu`` the weighted mean of the patches' mean colours and the gain
    ``g = sum w / sqrt(sum w^2 + rho ((sum w)^2 - sum w^2))``, which restores the contrast a
    linear blend of ``n`` uncorrelated patches divides by up to ``sqrt(n)``. ``rho`` is the
    texture's correlation at the spread of the overlapping patches' source offsets (a
    Gaussian of correlation length ``corr_len`` px): 1 for coherent patches (same source
    offset, g = 1), ~0 for unrelated ones.
    """
    w = np.maximum(accum[..., _W], 1e-9)
    lin = accum[..., _ACC] / w[..., None]
    if bands:
        return lin - accum[..., _FINE] / w[..., None] + accum[..., _OWN]
    if not preserve:
        return lin
    w2 = np.maximum(accum[..., _W2], 1e-18)
    q = np.maximum(w * w - w2, 0.0)
    mo = accum[..., _OFF] / w[..., None]
    spread2 = np.maximum(accum[..., _OFF2] / w - (mo ** 2).sum(-1), 0.0)
    d2 = 2.0 * spread2 * w * w / np.maximum(q, 1e-12)
    rho = np.exp(-d2 / (2.0 * corr_len ** 2))
    g = w / np.sqrt(w2 + rho * q)
    mu = accum[..., _MEAN] / w[..., None]
    return mu + (lin - mu) * g[..., None]


def correlation_length(frames: np.ndarray) -> float:
    """Correlation length (px) of the footage's texture: ``l`` with ``exp(-1 / (2 l^2))`` the
    correlation of the grey-level detail (minus a Gaussian local mean, sigma 4 px) between
    horizontally and vertically neighbouring pixels, averaged over up to 4 frames."""
    rs = []
    for f in frames[np.unique(np.linspace(0, len(frames) - 1, min(4, len(frames))).astype(int))]:
        g = np.asarray(f, np.float32).mean(-1)
        d = g - cv2.GaussianBlur(g, (0, 0), 4.0)
        for a, b in ((d[:, 1:], d[:, :-1]), (d[1:], d[:-1])):
            rs.append(float((a * b).sum() / max(np.sqrt((a * a).sum() * (b * b).sum()), 1e-12)))
    r1 = min(max(float(np.mean(rs)), 0.01), 0.999)
    return float(np.sqrt(-1.0 / (2.0 * np.log(r1))))


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


def _window_feature(win: np.ndarray, p: int) -> np.ndarray:
    """:func:`_block_features` of one ``(p, p, 2)`` window: ``(18,)``."""
    b = max(p // 3, 1)
    off = (p - 3 * b) // 2
    return win[off:off + 3 * b, off:off + 3 * b].reshape(3, b, 3, b, 2).mean((1, 3)).ravel()


def _bilinear_field(f: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    h, w, _ = f.shape
    x = np.clip(x, 0, w - 1.000001)
    y = np.clip(y, 0, h - 1.000001)
    j = x.astype(int)
    i = y.astype(int)
    gx = (x - j)[:, None]
    gy = (y - i)[:, None]
    return (f[i, j] * (1 - gx) + f[i, j + 1] * gx) * (1 - gy) + (f[i + 1, j] * (1 - gx) + f[i + 1, j + 1] * gx) * gy


def obstacle_alpha(mask: np.ndarray, width: float) -> np.ndarray:
    """Opacity ``(H, W)`` of an obstacle's fill: 1 on the mask (the declared solid shows only
    the footage), outside a linear ramp to 0 over ``width`` px, ``1 - (d - 0.5) / width`` with
    ``d`` the distance (px) of the pixel from the nearest mask pixel (no seam at the edge)."""
    m = np.asarray(mask, bool)
    if not m.any():
        return np.zeros(m.shape)
    d_out = cv2.distanceTransform((~m).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return np.where(m, 1.0, np.clip(1.0 - (d_out - 0.5) / max(float(width), 1.0), 0.0, 1.0))


@dataclass(frozen=True)
class Transplant:
    """An obstacle the edit adds, drawn with the appearance of an obstacle in the footage: output
    pixel ``(x, y)`` shows the source's per-pixel temporal median at
    ``src_center + scale * ((x, y) - center)`` (px, per axis; ``scale`` = the footage obstacle's
    half-size over the added one's), over ``mask`` ``(H, W)`` bool (the added obstacle) at
    opacity 1 and a ramp outside it (:func:`obstacle_alpha`), like an obstacle in the footage."""

    mask: np.ndarray
    center: tuple[float, float]
    src_center: tuple[float, float]
    scale: tuple[float, float]

    def image(self, median: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        """``(H, W, C)`` the ``median`` (source-sized, float) mapped onto the output (bilinear,
        edge pixels repeated past the source's border)."""
        yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float32)
        mx = (self.src_center[0] + self.scale[0] * (xx - self.center[0])).astype(np.float32)
        my = (self.src_center[1] + self.scale[1] * (yy - self.center[1])).astype(np.float32)
        return cv2.remap(np.asarray(median, np.float32), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def _touches(integral: np.ndarray, y: np.ndarray, x: np.ndarray, p: int) -> np.ndarray:
    """Whether the ``p x p`` windows with top-left (y, x) (ints, inside the frame) hold any set
    pixel of the mask whose summed-area table (padded by one row and column) is ``integral``."""
    y, x = np.asarray(y, int), np.asarray(x, int)
    return (integral[y + p, x + p] - integral[y, x + p] - integral[y + p, x] + integral[y, x]) > 0


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
    fluid: np.ndarray  # texture from the fluid's pool (must not drift onto the footage's obstacles)

    @classmethod
    def empty(cls) -> "_Patches":
        f = np.zeros(0)
        return cls(f, f.copy(), np.zeros(0, np.int64), f.copy(), f.copy(), f.copy(), f.copy(), np.zeros(0, np.int64),
                   np.zeros(0, bool))

    def append(self, cx, cy, ts, sx, sy, alpha, dalpha, fluid=True) -> None:
        self.cx = np.append(self.cx, cx)
        self.cy = np.append(self.cy, cy)
        self.ts = np.append(self.ts, np.int64(ts))
        self.sx = np.append(self.sx, sx)
        self.sy = np.append(self.sy, sy)
        self.alpha = np.append(self.alpha, alpha)
        self.dalpha = np.append(self.dalpha, dalpha)
        self.age = np.append(self.age, 0)
        self.fluid = np.append(self.fluid, bool(fluid))

    def keep(self, m: np.ndarray) -> None:
        for k in ("cx", "cy", "ts", "sx", "sy", "alpha", "dalpha", "age", "fluid"):
            setattr(self, k, getattr(self, k)[m])


def _consistency(win: np.ndarray, existing: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Colour consistency of candidate windows ``win`` (n, p, p, 3) with the filled output
    ``existing`` (p, p, 3) where ``mask`` (p, p) is 1: the mean squared difference written as
    mean + contrast + structure, ``dmu^2 + (s_a - s_b)^2 + 2 s_b^2 (1 - rho)`` per channel
    (a = candidate, b = output), with the structure term at the output's contrast ``s_b``
    instead of ``s_a s_b``. Plain L2 favours low-contrast candidates (their structure term is
    small whatever they contain): the wash-out of patch-based synthesis."""
    m = mask > 0
    a = win[:, m]                      # (n, m, 3)
    b = existing[m]                    # (m, 3)
    ma, mb = a.mean(1), b.mean(0)
    da, db = a - ma[:, None], b - mb
    va, vb = (da * da).mean(1), (db * db).mean(0)
    cov = (da * db).mean(1)
    sa, sb = np.sqrt(va), np.sqrt(vb)
    rho = cov / np.maximum(sa * sb, 1e-12)
    return ((ma - mb) ** 2 + (sa - sb) ** 2 + 2.0 * vb * (1.0 - rho)).mean(1)


class PatchSelector:
    """PATCHSELECT (seed 5.4): velocity-neighbourhood candidates from a KD-tree, then colour
    consistency with the filled output and uniform use of the source.

    With ``blocked`` (source-sized bool: pixels of obstacles in the footage, as the render shows
    them) the candidates form two pools: ``"fluid"``, the windows touching no blocked pixel,
    and ``"solid"``, the windows centred on a pixel of ``solid`` (the footage's obstacles), for
    obstacles the edit adds. Without it every candidate is in the fluid pool."""

    def __init__(self, src: np.ndarray, src_flow: np.ndarray, p: int, k: int, min_life: int,
                 stride: int = 2, max_patches: int = 60000, seed: int = 0, margin: int = 4,
                 tolerance: float = 0.5, velocity_noise: float = 0.0, usage_weight: float = 0.0,
                 blocked: np.ndarray | None = None, solid: np.ndarray | None = None) -> None:
        T, hs, ws = src.shape[:3]
        self.src, self.p, self.k = src, p, k
        self.tolerance, self.usage_weight = tolerance, usage_weight
        # data costs (px^2/frame^2 per feature element) closer than the flow's accuracy are ties
        self.data_floor = velocity_noise ** 2
        self.radius = velocity_noise * np.sqrt(18.0)
        self.probe = 512
        last = max(T - 1 - min_life, 0) if T >= 16 else T - 1
        frames = np.arange(0, min(last, src_flow.shape[0] - 1) + 1)
        self.last = int(frames[-1])
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
        self.feats = np.concatenate(feats).astype(np.float32)
        self.where = np.concatenate(where)
        self.blocked = None
        pools = {"fluid": np.arange(len(self.feats))}
        if blocked is not None and np.any(blocked):
            self.blocked = np.pad(np.cumsum(np.cumsum(np.asarray(blocked, np.int64), 0), 1), ((1, 0), (1, 0)))
            self.solid = np.asarray(solid if solid is not None else blocked, bool)
            pools = {name: np.flatnonzero(self.in_pool(name, self.where[:, 1], self.where[:, 2]))
                     for name in ("fluid", "solid")}
            if len(pools["fluid"]) == 0:
                raise RenderInputError("every source patch touches an obstacle in the footage: no fluid texture left")
        self.pools = {name: ids for name, ids in pools.items() if len(ids)}
        self.trees = {name: cKDTree(self.feats[ids]) for name, ids in self.pools.items()}
        # use of the source by the live output patches, per cell of p/2 px (uniformity)
        self.cell = max(p // 2, 1)
        self.usage = np.zeros((hs // self.cell + 1, ws // self.cell + 1))
        self.cover = np.zeros(self.usage.shape, bool)
        for y, x in np.unique(self.where[:, 1:], axis=0):
            self.cover[self._cells(y, x)] = True
        self.usage_sum = 0.0

    def in_pool(self, pool: str, y: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Whether the source windows with top-left (y, x) belong to ``pool`` (see the class)."""
        y, x = np.asarray(y, int), np.asarray(x, int)
        if self.blocked is None:
            return np.full(y.shape, pool == "fluid")
        if pool == "fluid":
            return ~_touches(self.blocked, y, x, self.p)
        return self.solid[y + self.p // 2, x + self.p // 2]

    def _cells(self, y: int, x: int) -> tuple[slice, slice]:
        c = self.cell
        return slice(int(y) // c, (int(y) + self.p - 1) // c + 1), slice(int(x) // c, (int(x) + self.p - 1) // c + 1)

    def set_usage(self, sy: np.ndarray, sx: np.ndarray, weight: np.ndarray) -> None:
        """Use of the source by the live patches (source windows at ``sy, sx``, weights
        ``weight`` = opacity): how many output patches each source cell currently feeds."""
        self.usage[:] = 0.0
        y = np.clip(np.round(sy).astype(int), 0, None)
        x = np.clip(np.round(sx).astype(int), 0, None)
        for yy, xx, ok in self._cell_index(y, x):
            m = ok & (weight > 0)
            np.add.at(self.usage, (yy[m], xx[m]), weight[m])
        self.usage_sum = float(self.usage[self.cover].sum())

    def _cell_index(self, y: np.ndarray, x: np.ndarray):
        """For windows with top-left (y, x): per offset of the (up to) ceil(p/c)+1 squared
        cells they touch, the cell indices and whether the window touches that cell."""
        c, p = self.cell, self.p
        y0, y1, x0, x1 = y // c, (y + p - 1) // c + 1, x // c, (x + p - 1) // c + 1
        n = -(-p // c) + 1
        for dy in range(n):
            for dx in range(n):
                ok = (y0 + dy < y1) & (x0 + dx < x1)
                yield np.minimum(y0 + dy, self.usage.shape[0] - 1), np.minimum(x0 + dx, self.usage.shape[1] - 1), ok

    def _use(self, y: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Mean use of the source cells under windows (y, x) over the mean use of the source."""
        mean = self.usage_sum / max(int(self.cover.sum()), 1)
        if mean <= 0:
            return np.zeros(len(y))
        tot, cnt = np.zeros(len(y)), np.zeros(len(y))
        for yy, xx, ok in self._cell_index(y, x):
            tot += np.where(ok, self.usage[yy, xx], 0.0)
            cnt += ok
        return tot / cnt / mean

    def select(self, feature: np.ndarray, existing: np.ndarray | None, mask: np.ndarray | None,
               coherent: list[tuple[int, int, int]] = (), src_flow: np.ndarray | None = None,
               pool: str = "fluid") -> tuple[tuple[int, int, int], float]:
        """PATCHSELECT for one output patch.

        Candidates: the K nearest velocity patches of the video, K drawn at random among all
        video patches within the flow's accuracy of the query (``velocity_noise`` RMS per
        feature element; the K nearest alone crowd into one region of the source wherever its
        flow happens to be a hair closer), and "coherent" candidates (the source windows that
        continue already placed overlapping patches, as in Ashikhmin's coherent synthesis).

        Choice, in two stages: (1) velocity: keep the candidates whose data cost (mean
        squared velocity-feature distance, px^2/frame^2) is within ``tolerance`` of the best
        plus ``velocity_noise^2``; (2) appearance: among them, colour consistency with the
        already filled output (:func:`_consistency`) times ``1 + usage_weight x`` the relative
        use of the candidate's source cells by the live output (uniform patch usage, as in
        Jamriska et al. 2015); draw at random among those within ``tolerance`` of the lowest.

        All candidates, coherent ones included, come from ``pool`` ("fluid" or "solid", see the
        class; "solid" falls back to "fluid" when the footage has no obstacle).

        Returns:
            the chosen source ``(t, y, x)`` and its data cost.
        """
        pool = pool if pool in self.pools else "fluid"
        members = self.pools[pool]
        d, idx = self.trees[pool].query(feature, k=min(self.k, len(members)), eps=0.5)
        ids, ds = [members[np.atleast_1d(idx)]], [np.atleast_1d(d)]
        if self.radius > 0:
            # uniform draw from the ball by rejection: test a random sample of the video patches
            probe = members[self.rng.integers(0, len(members), min(self.probe, len(members)))]
            dp = np.sqrt(((self.feats[probe] - feature) ** 2).sum(1))
            inside = np.flatnonzero(dp <= self.radius)[:self.k]
            ids.append(probe[inside])
            ds.append(dp[inside])
        cand = self.where[np.concatenate(ids)]
        data = np.concatenate(ds) ** 2 / 18.0
        p = self.p
        T, hs, ws = self.src.shape[:3]
        coh = [(t, y, x) for t, y, x in coherent if 0 <= t < T and 0 <= y <= hs - p and 0 <= x <= ws - p]
        if coh:
            coh = [c for c, ok in zip(coh, self.in_pool(pool, [c[1] for c in coh], [c[2] for c in coh])) if ok]
        if coh and src_flow is not None:
            f = np.stack([_window_feature(src_flow[t, y:y + p, x:x + p], p) for t, y, x in coh])
            cand = np.concatenate([cand, np.array(coh, dtype=cand.dtype)])
            data = np.r_[data, ((f - feature) ** 2).sum(1) / 18.0]
        good = np.flatnonzero(data <= data.min() * (1.0 + self.tolerance) + self.data_floor)
        t, y, x = cand[good].T
        e = np.ones(len(good))
        if existing is not None and mask is not None and mask.sum() > 0:
            r = np.arange(p)
            win = self.src[t[:, None, None], y[:, None, None] + r[None, :, None], x[:, None, None] + r[None, None, :]]
            e = 1e-4 + _consistency(win, existing, mask)
        if self.usage_weight > 0:
            e = e * (1.0 + self.usage_weight * self._use(y, x))
        # diversity: draw among the good ones, so that a uniform field does not repeat one
        # source patch (texture-by-numbers "pick among good")
        best = int(self.rng.choice(np.flatnonzero(e <= e.min() * (1.0 + self.tolerance) + 1e-12)))
        cells = self._cells(y[best], x[best])
        self.usage[cells] += 1.0
        self.usage_sum += float(self.cover[cells].sum())
        return (int(t[best]), int(y[best]), int(x[best])), float(data[good[best]])


def render_sequence(src_frames: np.ndarray, src_flow: np.ndarray, edited_field: np.ndarray, n_frames: int,
                    rng: np.random.Generator, settings: RenderSettings | None = None,
                    solid: np.ndarray | None = None,
                    match_flow: np.ndarray | None = None,
                    footage_solid: np.ndarray | None = None,
                    transplants: list[Transplant] | tuple[Transplant, ...] = (),
                    on_frame: Callable[[int], None] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
    """Render ``n_frames`` of the edited field by texture transfer from the source video.

    Args:
        src_frames: ``(T, Hs, Ws, 3)`` uint8 source video.
        src_flow: ``(T-1, Hs, Ws, 2)`` its optical flow (px/frame), e.g. :func:`estimate_flow`.
        edited_field: ``(H, W, 2)`` edited velocity (px/frame at output resolution), or
            ``(n_frames, H, W, 2)`` one field per output frame.
        n_frames: output frames.
        rng: random generator (seeds the candidate subsampling).
        settings: patch size, overlap, K, mode, candidate search, blend; defaults of
            :class:`RenderSettings`.
        solid: optional ``(H, W)`` obstacle mask of the output (after frame 0 patches are not
            spawned centred inside it, unless a pixel outside the fills in their window would
            be left bare; it gets colour from zero-velocity source patches, which hold their
            source frame there).
        match_flow: flow the velocity patches are matched on (default ``src_flow``).
        footage_solid: optional ``(H, W)`` mask of the obstacles that are in the footage at
            the same place (output pixel = source pixel): they show the source's temporal median,
            blended over ``overlap`` px outside their edge, and no fluid patch takes texture from
            what that fill shows; the rest of ``solid`` (obstacles the edit adds) takes texture
            from windows centred in them, unless they are ``transplants``.
        transplants: obstacles the edit adds, each drawn as the source's temporal median of an
            obstacle in the footage mapped onto its shape (:class:`Transplant`), blended like
            ``footage_solid``'s fill; no patch is spawned centred in them, and where that leaves
            their ring less than fully covered, the patches count by their coverage.
        on_frame: optional callback ``on_frame(n)`` after output frame ``n`` (progress lines).

    Returns:
        ``(n_frames, H, W, 3)`` uint8 frames and figures: ``time_per_frame_s``,
        ``patches_mean``, ``spawned``, ``data_cost_mean`` (mean squared velocity-feature
        distance of the chosen patches, px^2/frame^2), ``bare_pixels`` (output pixels that show
        the patches, i.e. no in-footage fill covers them fully and no transplant at all, and that
        no patch covers, summed over the frames: 0 by construction, since the hole filler's last
        pass covers every such pixel; a check, not a measurement), ``bare_before_last_pass`` (the
        same count before that pass: what the cells' own rules left) and ``spawned_on_bare``
        (patches that last pass spawned).
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
    # the settings' names (EditSpec.from_dict checks them too, but a RenderSettings built in Python is not)
    for key, allowed in (("mode", ("advected", "fixed")), ("blend", ("linear", "variance", "multiband")),
                         ("resample", ("cubic", "linear"))):
        if getattr(s, key) not in allowed:
            raise RenderInputError(f"render.{key}={getattr(s, key)!r}, expected one of {list(allowed)}")
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
    if solid is not None and np.shape(solid) != (H, W):
        raise RenderInputError(f"solid shape {np.shape(solid)}, expected {(H, W)}")
    fill = fill_alpha = blocked = src_solid = None
    added = solid
    if footage_solid is not None and np.any(footage_solid):
        fs = np.asarray(footage_solid, bool)
        if fs.shape != (H, W):
            raise RenderInputError(f"footage_solid shape {fs.shape}, expected {(H, W)}")
        # a solid in the footage is static: the per-pixel temporal median of the source is its
        # appearance without camera noise and passing fluid (and needs no clip as long as the output)
        median = np.median(src, axis=0)
        fill = median[:H, :W]
        fill_alpha = obstacle_alpha(fs, o)[..., None]
        blocked = np.zeros(src.shape[1:3], bool)
        blocked[:H, :W] = fill_alpha[..., 0] > 0
        src_solid = np.zeros(src.shape[1:3], bool)
        src_solid[:H, :W] = fs
        added = None if solid is None else np.asarray(solid, bool) & ~fs
    tp_colour = tp_alpha = hide = None
    if len(transplants):
        if fill is None:
            median = np.median(src, axis=0)
        tp_colour, tp_alpha = np.zeros((H, W, 3)), np.zeros((H, W, 1))
        # every obstacle's pixels: an added obstacle's blend ring must not paint over another solid
        # (it would lay the source obstacle's surroundings over it)
        others = np.zeros((H, W), bool)
        for m in (solid, footage_solid):
            if m is not None:
                others |= np.asarray(m, bool)
        for tp in transplants:
            if np.shape(tp.mask) != (H, W):
                raise RenderInputError(f"transplant mask shape {np.shape(tp.mask)}, expected {(H, W)}")
            a = obstacle_alpha(tp.mask, o)[..., None]
            a[others & ~np.asarray(tp.mask, bool)] = 0.0
            tp_colour = a * tp.image(median, (H, W)) + (1.0 - a) * tp_colour  # premultiplied, later on top
            tp_alpha = a + (1.0 - a) * tp_alpha
        hide = np.any([np.asarray(tp.mask, bool) for tp in transplants], axis=0)
        if added is not None:
            added = np.asarray(added, bool) & ~hide
    sel = PatchSelector(src, mflow, p, s.k, min_life, seed=int(rng.integers(1 << 31)),
                        velocity_noise=s.velocity_noise, usage_weight=s.usage, blocked=blocked, solid=src_solid)
    step = p - o
    # the grid reaches ``o`` px past the frame, so that edge pixels get a patch's full weight
    # (an inflow edge otherwise opens an uncovered strip as soon as its patches move in)
    grid_y = np.unique(np.r_[np.arange(-o, H - p + o + 1, step), H - p + o])
    grid_x = np.unique(np.r_[np.arange(-o, W - p + o + 1, step), W - p + o])
    # the pixels that show the patches (no fill covers them fully), padded like the accumulator:
    # one no patch covers there renders black, or darkened in the in-footage fill's ramp
    shows_patches = np.ones((H, W), bool)
    if fill_alpha is not None:
        shows_patches &= fill_alpha[..., 0] < 1
    if tp_alpha is not None:
        shows_patches &= tp_alpha[..., 0] == 0
    shows_patches = np.pad(shows_patches, o, constant_values=False)
    advect = s.mode == "advected"
    cubic = s.resample == "cubic"
    corr_len = correlation_length(src_frames)
    preserve = s.blend == "variance"
    bands = s.blend == "multiband"
    # the fine band: scales finer than the feather's ramp, which a linear cross-fade averages away
    fine = fine_band(src, BAND_SIGMA_PER_OVERLAP * max(o, 1)) if bands else np.zeros((1, 1, 1, 3), np.float32)
    P = _Patches.empty()
    out = np.empty((n_frames, H, W, 3), np.uint8)
    spawned = bare_pixels = bare_before_last = spawned_on_bare = 0
    last_spawn: dict[tuple[int, int], int] = {}
    costs: list[float] = []
    n_live: list[int] = []
    t0 = time.perf_counter()

    def spawn(cx: int, cy: int, alpha: float) -> None:
        nonlocal spawned
        feat = _window_feature(fpad[cy + o:cy + o + p, cx + o:cx + o + p], p)
        win = accum[cy + o:cy + o + p, cx + o:cx + o + p]
        mask = (win[..., _W] > 0.05).astype(np.float64)
        existing = _compose(win, preserve, corr_len, bands)
        near = np.flatnonzero((np.abs(P.cx - cx) < p - o) & (np.abs(P.cy - cy) < p - o) & (P.alpha > 0.5))
        # continuations of the overlapping patches; one whose source clip is ending continues
        # from the start of the clip (rewound: for static texture the same content)
        coh = [(int(P.ts[j]) % (sel.last + 1), int(round(P.sy[j] + cy - P.cy[j])), int(round(P.sx[j] + cx - P.cx[j])))
               for j in near[-4:]]
        # an obstacle the edit adds takes solid texture; everything else the fluid's
        ic, jc = min(max(cy + p // 2, 0), H - 1), min(max(cx + p // 2, 0), W - 1)
        pool = "solid" if added is not None and added[ic, jc] else "fluid"
        (t, y, x), c = sel.select(feat, existing, mask, coh, mflow, pool=pool)
        P.append(cx, cy, t, x, y, alpha, 1.0 / fade if alpha < 1 else 0.0, sel.in_pool("fluid", y, x))
        _splat(src, p, o, P.cx[-1:] + o, P.cy[-1:] + o, P.ts[-1:], P.sx[-1:], P.sy[-1:], P.alpha[-1:], n, accum, True,
               cubic, fine)
        spawned += 1
        costs.append(c)

    def uncovered(win: tuple[slice, slice] = np.s_[:, :]) -> np.ndarray:
        """The pixels of ``win`` of the (padded) accumulator no patch covers that show the patches."""
        return (accum[win][..., _W] < 1e-6) & shows_patches[win]

    for n in range(n_frames):
        field = ef[min(n, ef.shape[0] - 1)]
        if n > 0 and len(P.cx):
            sx0, sy0 = P.sx.copy(), P.sy.copy()
            if advect:
                v = _bilinear_field(field, P.cx + p / 2, P.cy + p / 2)
                P.cx = P.cx + v[:, 0]
                P.cy = P.cy + v[:, 1]
            if temporal:
                # patches centred on an obstacle hold their source frame: a solid does not change
                live = np.ones(len(P.cx), bool) if solid is None else ~solid[
                    np.clip(P.cy + p / 2, 0, H - 1).astype(int), np.clip(P.cx + p / 2, 0, W - 1).astype(int)]
                if advect:
                    vs = _sample_flows(sflow, P.ts, P.sx + p / 2, P.sy + p / 2)
                    P.sx = P.sx + vs[:, 0] * live
                    P.sy = P.sy + vs[:, 1] * live
                P.ts = np.minimum(P.ts + live, T - 1)
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
            if sel.blocked is not None and temporal and advect:
                # a fluid patch whose source window would drift onto a footage obstacle stays
                # where it was and fades out
                onto = P.fluid & ~sel.in_pool("fluid", np.round(P.sy), np.round(P.sx))
                P.sx[onto], P.sy[onto] = sx0[onto], sy0[onto]
                P.dalpha[onto & (P.dalpha >= 0)] = -1.0 / fade
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
        # accumulator and field padded by ``o`` px (patches reaching past the frame)
        accum = np.zeros((H + 2 * o, W + 2 * o, _N_ACC))
        fpad = np.pad(field, ((o, o), (o, o), (0, 0)), mode="edge")
        if len(P.cx):
            _splat(src, p, o, P.cx + o, P.cy + o, P.ts, P.sx, P.sy, P.alpha, n, accum, True, cubic, fine)
        sel.set_usage(P.sy, P.sx, P.alpha)
        # fill holes (all of frame 0) in raster order: a cell whose own part (its patch minus
        # the overlaps) is under-covered on average or has an uncovered pixel, or whose window
        # has an uncovered pixel that shows the patches anywhere, in the overlaps with its
        # neighbours' windows and their corners too (no cell's own part holds those)
        any_bare = bool(uncovered().any())
        for gy in grid_y:
            for gx in grid_x:
                cov = accum[gy + 2 * o:gy + p, gx + 2 * o:gx + p, _W]
                win = np.s_[gy + o:gy + p + o, gx + o:gx + p + o]
                shows_bare = any_bare and bool(uncovered(win).any())
                bare = shows_bare or bool(cov.size and cov.min() < 1e-6)
                if cov.size and (cov.mean() < 0.9 or bare):
                    if hide is not None and hide[gy + p // 2, gx + p // 2]:
                        # a transplanted obstacle: its fill, not a patch, where the fill covers
                        # the cell's own part (with a small overlap or obstacle it may not)
                        own = tp_alpha[max(gy + o, 0):min(gy + p - o, H), max(gx + o, 0):min(gx + p - o, W), 0]
                        if own.size == 0 or (own > 0).all():
                            continue
                    # (a bare pixel in its window does not override this: the last pass below
                    # covers it with a patch centred on the pixel itself, from the pool there)
                    if solid is not None and n > 0 and solid[gy + p // 2, gx + p // 2] and cov.mean() > 0.2:
                        continue
                    # a patch spawned here is still fading in: wait for it unless pixels are bare
                    if n - last_spawn.get((gy, gx), -fade) < fade and not bare:
                        continue
                    last_spawn[(gy, gx)] = n
                    spawn(int(gx), int(gy), 1.0 if n == 0 else 0.35)
        # a bare pixel no cell took (each cell whose window holds it is centred in a transplanted
        # obstacle whose fill covers its own part): a patch centred on it
        left = uncovered()
        bare_before_last += int(left.sum())
        for i, j in np.argwhere(left):
            if accum[i, j, _W] < 1e-6:
                spawned_on_bare += 1
                spawn(min(max(int(j) - o - p // 2, -o), W - p + o), min(max(int(i) - o - p // 2, -o), H - p + o),
                      1.0 if n == 0 else 0.35)
        bare_pixels += int(uncovered().sum())
        img = _compose(accum[o:o + H, o:o + W], preserve, corr_len, bands)
        if fill is not None:
            img = fill_alpha * fill + (1.0 - fill_alpha) * img
        if tp_colour is not None:
            # no patch is centred in a transplanted obstacle: in its ring the patches count by
            # their coverage (a bare pixel shows the fill alone, not black)
            c = np.minimum(accum[o:o + H, o:o + W, _W], 1.0)[..., None]
            if fill is not None:
                c = fill_alpha + (1.0 - fill_alpha) * c
            over = (tp_colour + (1.0 - tp_alpha) * c * img) / np.maximum(tp_alpha + (1.0 - tp_alpha) * c, 1e-9)
            img = np.where(tp_alpha > 0, over, img)
        out[n] = np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)
        n_live.append(len(P.cx))
        if on_frame is not None:
            on_frame(n)
    dt = time.perf_counter() - t0
    figs = {"time_per_frame_s": dt / n_frames, "patches_mean": float(np.mean(n_live)), "spawned": spawned,
            "data_cost_mean": float(np.mean(costs)) if costs else 0.0, "bare_pixels": bare_pixels,
            "bare_before_last_pass": bare_before_last, "spawned_on_bare": spawned_on_bare, "mode": s.mode,
            "source_temporal": temporal, "source_candidates": len(sel.feats),
            "source_candidates_fluid": len(sel.pools["fluid"]), "transplanted_obstacles": len(transplants)}
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
