"""Source-sink optimisation of an edited velocity field (seed section 5.3, eq. 17-32).

The field ``v`` is ``(H, W, 2)`` in grid nodes per frame on the edit grid. The objective is
``alpha * Ef + beta * Es + gamma * En`` (eq. 17):

* ``Ef`` flow conservation: mean over source particles of the squared distance from the
  particle's exit point to its desired sink (eq. 18, ``c_des . d^2``). Particles are traced
  along the streamlines of the field (arc-length steps, so the exit point depends on the
  direction field only). Its gradient with respect to every node velocity is computed by
  reverse-mode differentiation through the discrete trace (the adjoint of the finite-difference
  gradient of eq. 22). It is exact for particles that end within the step limit (in a sink, on
  an obstacle or at the frame edge; a test checks it against central differences). For a
  particle still circulating at the step limit the adjoint is clipped to keep it bounded, so its
  contribution is a bounded descent direction, not the exact derivative.
* ``Es`` smoothness: sum over 4-connected pairs of ``|v_i - v_j|^2`` (eq. 23-24), per node.
* ``En`` neighbourhood: squared distance of every node's 3x3 velocity patch to its nearest
  patch of the video field (eq. 25-29), nearest neighbours by a KD-tree; its gradient holds the
  matches fixed (exact almost everywhere).

The local minimum of the continuous formulation (seed Figure 15) is avoided by the
initialisation of :func:`harmonic_init`: per sink, in order, shortest paths (Dijkstra, 8-connected)
from its source nodes claim channels that are walls for the sinks after it; per sink, a
flux-driven potential (the graph Poisson equation with unit injection at the sink's own source
nodes, Dirichlet 0 on the sink, Neumann at walls: obstacles, the frame edge, other sinks, other
sinks' sources and their channels) has its only minimum on the sink, so steepest descent from any
node connected to it ends there; the field in the region nearest each channel follows the sum of
the directions of that potential and of the geodesic distance to the sink, and on and beside the
channels the channel's own direction.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse import csgraph
from numba import njit
from scipy.ndimage import distance_transform_edt
from scipy.spatial import cKDTree

from vidsim.fluid.edit import EditProblem, EditSpec

_EPS = 1e-3


@njit(cache=True)
def _bilinear(v: np.ndarray, x: float, y: float):
    h, w, _ = v.shape
    cx = min(max(x, 0.0), w - 1.000001)
    cy = min(max(y, 0.0), h - 1.000001)
    inx = 1.0 if (x >= 0.0 and x <= w - 1.000001) else 0.0
    iny = 1.0 if (y >= 0.0 and y <= h - 1.000001) else 0.0
    j = int(cx)
    i = int(cy)
    fx = cx - j
    fy = cy - i
    v00 = v[i, j]
    v01 = v[i, j + 1]
    v10 = v[i + 1, j]
    v11 = v[i + 1, j + 1]
    val = (v00 * (1 - fx) + v01 * fx) * (1 - fy) + (v10 * (1 - fx) + v11 * fx) * fy
    dvdx = ((v01 - v00) * (1 - fy) + (v11 - v10) * fy) * inx
    dvdy = ((v10 - v00) * (1 - fx) + (v11 - v01) * fx) * iny
    return val, dvdx, dvdy, i, j, fx, fy


@njit(cache=True)
def _terminal(x: float, y: float, sink_id: np.ndarray, solid: np.ndarray) -> int:
    """-3 running, -2 left the frame, -1 hit an obstacle, k >= 0 entered sink k."""
    h, w = sink_id.shape
    if x < -0.5 or y < -0.5 or x > w - 0.5 or y > h - 0.5:
        return -2
    i = min(max(int(y + 0.5), 0), h - 1)
    j = min(max(int(x + 0.5), 0), w - 1)
    if sink_id[i, j] >= 0:
        return sink_id[i, j]
    if solid[i, j]:
        return -1
    return -3


@njit(cache=True)
def trace_particles(v, particles, desired, sink_boxes, sink_id, solid, step, max_steps, want_grad):
    """Trace every particle to its exit point and (optionally) back-propagate ``Ef``.

    Returns:
        exits ``(M, 2)``, exit codes ``(M,)`` (sink index, -1 obstacle, -2 frame edge, -3 did
        not exit within ``max_steps``), per-particle errors ``(M,)`` (squared distance to the
        desired sink) and, if ``want_grad``, the gradient of their sum w.r.t. ``v`` (H, W, 2).
    """
    h, w, _ = v.shape
    m = particles.shape[0]
    exits = np.empty((m, 2))
    codes = np.empty(m, np.int64)
    errs = np.empty(m)
    grad = np.zeros((h, w, 2))
    xs = np.empty((max_steps + 1, 2))
    for p in range(m):
        x = particles[p, 0]
        y = particles[p, 1]
        xs[0, 0] = x
        xs[0, 1] = y
        n = 0
        start = _terminal(x, y, sink_id, solid)
        # a source node inside another sink or an obstacle: the particle leaves that region before
        # it can end anywhere (it does not end where it starts); inside its own sink it has arrived
        escaping = start >= -1 and start != desired[p]
        code = start if start == desired[p] else -3
        while n < max_steps:
            val, _, _, _, _, _, _ = _bilinear(v, x, y)
            s = np.sqrt(val[0] ** 2 + val[1] ** 2 + _EPS**2)
            x = x + step * val[0] / s
            y = y + step * val[1] / s
            n += 1
            xs[n, 0] = x
            xs[n, 1] = y
            code = _terminal(x, y, sink_id, solid)
            if escaping:
                if code == start:
                    continue  # still inside the region it started in
                escaping = False
            if code != -3:
                break
        exits[p, 0] = x
        exits[p, 1] = y
        codes[p] = code
        k = desired[p]
        cx = min(max(x, sink_boxes[k, 0] - 0.5), sink_boxes[k, 2] + 0.5)
        cy = min(max(y, sink_boxes[k, 1] - 0.5), sink_boxes[k, 3] + 0.5)
        errs[p] = (x - cx) ** 2 + (y - cy) ** 2
        if not want_grad or errs[p] == 0.0:
            continue
        lx = 2.0 * (x - cx)
        ly = 2.0 * (y - cy)
        lam_max = 1e3 * (np.sqrt(lx * lx + ly * ly) + 1.0)
        for t in range(n - 1, -1, -1):
            val, dvdx, dvdy, i, j, fx, fy = _bilinear(v, xs[t, 0], xs[t, 1])
            s2 = val[0] ** 2 + val[1] ** 2 + _EPS**2
            s = np.sqrt(s2)
            s3 = s2 * s
            j00 = 1.0 / s - val[0] * val[0] / s3
            j01 = -val[0] * val[1] / s3
            j11 = 1.0 / s - val[1] * val[1] / s3
            mx = step * (j00 * lx + j01 * ly)
            my = step * (j01 * lx + j11 * ly)
            w00 = (1 - fx) * (1 - fy)
            w01 = fx * (1 - fy)
            w10 = (1 - fx) * fy
            w11 = fx * fy
            grad[i, j, 0] += w00 * mx
            grad[i, j, 1] += w00 * my
            grad[i, j + 1, 0] += w01 * mx
            grad[i, j + 1, 1] += w01 * my
            grad[i + 1, j, 0] += w10 * mx
            grad[i + 1, j, 1] += w10 * my
            grad[i + 1, j + 1, 0] += w11 * mx
            grad[i + 1, j + 1, 1] += w11 * my
            # lambda_t = lambda_{t+1} + Dv^T mu
            nlx = lx + dvdx[0] * mx + dvdx[1] * my
            nly = ly + dvdy[0] * mx + dvdy[1] * my
            nrm = np.sqrt(nlx * nlx + nly * nly)
            if nrm > lam_max:  # long stagnating traces: keep the adjoint bounded
                nlx *= lam_max / nrm
                nly *= lam_max / nrm
            lx = nlx
            ly = nly
    return exits, codes, errs, grad


@njit(cache=True)
def travel_frames(v, particles, desired, sink_id, solid, step, max_steps):
    """Frames each particle takes along its traced path (the path of :func:`trace_particles`,
    same steps): the sum over steps of ``step / s``, ``s`` the regularised speed the tracer
    divides by (nodes/frame), i.e. the time to cover each step's displacement at the local
    speed. ``(M,)``; 0 for a particle that starts in its desired sink, ``inf`` for one that
    does not end within ``max_steps``."""
    m = particles.shape[0]
    out = np.empty(m)
    for p in range(m):
        x = particles[p, 0]
        y = particles[p, 1]
        start = _terminal(x, y, sink_id, solid)
        escaping = start >= -1 and start != desired[p]
        code = start if start == desired[p] else -3
        t = 0.0
        n = 0
        while code == -3 or escaping:
            if n >= max_steps:
                break
            val, _, _, _, _, _, _ = _bilinear(v, x, y)
            s = np.sqrt(val[0] ** 2 + val[1] ** 2 + _EPS**2)
            x = x + step * val[0] / s
            y = y + step * val[1] / s
            t += step / s
            n += 1
            code = _terminal(x, y, sink_id, solid)
            if escaping:
                if code == start:
                    continue
                escaping = False
        out[p] = t if code != -3 else np.inf
    return out


def smoothness(v: np.ndarray) -> tuple[float, np.ndarray]:
    """Eq. 23-24 summed over 4-connected pairs and divided by the node count."""
    dx = v[:, 1:] - v[:, :-1]
    dy = v[1:] - v[:-1]
    n = v.shape[0] * v.shape[1]
    e = (float((dx**2).sum()) + float((dy**2).sum())) / n
    g = np.zeros_like(v)
    g[:, 1:] += 2 * dx
    g[:, :-1] -= 2 * dx
    g[1:] += 2 * dy
    g[:-1] -= 2 * dy
    return e, g / n


def _patches(v: np.ndarray, r: int = 1) -> np.ndarray:
    h, w, _ = v.shape
    pad = np.pad(v, ((r, r), (r, r), (0, 0)), mode="edge")
    cols = [pad[dy:dy + h, dx:dx + w] for dy in range(2 * r + 1) for dx in range(2 * r + 1)]
    return np.concatenate(cols, axis=-1).reshape(h * w, -1)


class PatchIndex:
    """KD-tree over the video's 3x3 velocity patches (18-vectors), for eq. 25-27."""

    def __init__(self, video_fields: np.ndarray, max_patches: int = 40000, seed: int = 0) -> None:
        """Args:
            video_fields: ``(F, H, W, 2)`` or ``(H, W, 2)`` velocity fields of the video at the
                edit grid's resolution (nodes per frame).
            max_patches: random subset size kept in the tree (seeded).
        """
        vf = np.asarray(video_fields, dtype=np.float64)
        if vf.ndim == 3:
            vf = vf[None]
        if vf.ndim != 4 or vf.shape[-1] != 2:
            raise ValueError(f"video_fields shape {vf.shape}, expected (F,H,W,2) or (H,W,2)")
        pats = np.concatenate([_patches(f) for f in vf])
        if len(pats) > max_patches:
            pats = pats[np.random.default_rng(seed).choice(len(pats), max_patches, replace=False)]
        self.patches = pats
        self.tree = cKDTree(pats)

    def query(self, v: np.ndarray, k: int = 1, eps: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """Nearest video patches of each node's patch: distances and indices ``(H*W[, k])``.

        ``eps`` > 0 makes the search approximate: the neighbour returned is within ``1 + eps``
        times the true nearest distance (measured about 50x faster than exact at 64x64 on the
        stream footage, with mean distances equal to 4 digits).
        """
        return self.tree.query(_patches(v), k=k, eps=eps)


def neighborhood(v: np.ndarray, index: PatchIndex, offset: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """Eq. 28-30: sum of squared patch distances to the nearest video patch, per node."""
    h, w, _ = v.shape
    u = v if offset is None else v - offset
    _, idx = index.query(u)
    diff = (_patches(u) - index.patches[idx]).reshape(h, w, 9, 2)
    n = h * w
    e = float((diff**2).sum()) / n
    g = np.zeros((h + 2, w + 2, 2))
    k = 0
    for dy in range(3):
        for dx in range(3):
            g[dy:dy + h, dx:dx + w] += 2 * diff[:, :, k]
            k += 1
    # fold the edge padding back onto the border nodes
    g[1, :] += g[0, :]
    g[-2, :] += g[-1, :]
    g[:, 1] += g[:, 0]
    g[:, -2] += g[:, -1]
    return e, g[1:-1, 1:-1] / n


def _harmonic(free: np.ndarray, dirichlet_value: np.ndarray, injection: np.ndarray | None = None) -> np.ndarray:
    """Solve the graph Poisson equation ``-L phi = injection`` on ``free`` nodes (4-connected,
    Neumann at non-free nodes); ``dirichlet_value`` is NaN where unknown. Where
    ``injection`` is zero the solution is harmonic (no interior extremum)."""
    h, w = free.shape
    known = ~np.isnan(dirichlet_value)
    unk = free & ~known
    idx = -np.ones((h, w), np.int64)
    idx[unk] = np.arange(unk.sum())
    rows, cols, vals = [], [], []
    rhs = np.zeros(unk.sum())
    active = free | known
    for di, dj in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        a = np.zeros((h, w), bool)
        ys, xs = np.nonzero(unk)
        ny, nx = ys + di, xs + dj
        ok = (ny >= 0) & (ny < h) & (nx >= 0) & (nx < w)
        ys, xs, ny, nx = ys[ok], xs[ok], ny[ok], nx[ok]
        nb = active[ny, nx]
        ys, xs, ny, nx = ys[nb], xs[nb], ny[nb], nx[nb]
        r = idx[ys, xs]
        rows.append(r)
        cols.append(r)
        vals.append(np.ones(len(r)))
        nu = idx[ny, nx] >= 0
        rows.append(r[nu])
        cols.append(idx[ny, nx][nu])
        vals.append(-np.ones(nu.sum()))
        np.add.at(rhs, r[~nu], dirichlet_value[ny[~nu], nx[~nu]])
        del a
    n = unk.sum()
    kappa = 1e-9  # a tiny leak keeps regions cut off from every Dirichlet node solvable
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    A = A + kappa * sp.identity(n, format="csr")
    phi = np.full((h, w), 1.0)
    phi[known] = dirichlet_value[known]
    if injection is not None:
        rhs = rhs + injection[unk]
    phi[unk] = spla.spsolve(A.tocsc(), rhs + kappa)
    return phi


def _geodesic(ok: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shortest 8-connected path cost from every ``ok`` node to ``target`` nodes (Dijkstra;
    node cost ``1 + 3 / clearance`` keeps paths away from walls) and each node's next node
    toward the target (-1 none): ``(H, W)``, ``(H*W,)``."""
    h, w = ok.shape
    idx = np.arange(h * w).reshape(h, w)
    # keep clear of walls: a node next to an obstacle costs more to cross (1 + 3 / clearance)
    clear = distance_transform_edt(ok) if (~ok).any() else np.full((h, w), np.inf)
    cost = 1.0 + 3.0 / np.maximum(clear, 0.5)
    rows, cols, vals = [], [], []
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = ok[max(0, -di):h - max(0, di), max(0, -dj):w - max(0, dj)]
        b = ok[max(0, di):h + min(0, di) if di else h, max(0, dj):w + min(0, dj) if dj else w]
        ia = idx[max(0, -di):h - max(0, di), max(0, -dj):w - max(0, dj)]
        ib = idx[max(0, di):h + min(0, di) if di else h, max(0, dj):w + min(0, dj) if dj else w]
        m = a & b
        if di and dj:  # no corner cutting between two diagonal wall nodes
            c1 = ok[max(0, -di):h - max(0, di), max(0, dj):w + min(0, dj) if dj else w]
            c2 = ok[max(0, di):h + min(0, di) if di else h, max(0, -dj):w - max(0, dj)]
            m &= c1 & c2
        rows.append(ia[m])
        cols.append(ib[m])
        vals.append(np.hypot(di, dj) * 0.5 * (cost[max(0, -di):h - max(0, di), max(0, -dj):w - max(0, dj)][m]
                                               + cost[max(0, di):h + min(0, di) if di else h,
                                                      max(0, dj):w + min(0, dj) if dj else w][m]))
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    g = sp.csr_matrix((np.concatenate(vals), (r, c)), shape=(h * w, h * w))
    tg = np.flatnonzero((target & ok).ravel())
    if len(tg) == 0:
        return np.full((h, w), np.inf), -np.ones(h * w, np.int64)
    dist, pred, _ = csgraph.dijkstra(g, directed=False, indices=tg, min_only=True, return_predecessors=True)
    pred = np.where(pred < 0, -1, pred).astype(np.int64)
    return dist.reshape(h, w), pred


def harmonic_init(prob: EditProblem, speed: float = 1.0) -> tuple[np.ndarray, dict[str, Any]]:
    """Harmonic-potential initial field: every source node's steepest-descent path reaches
    its desired sink by construction (when the sink is reachable around the channels claimed
    before it; ``paths_ok`` reports the share that did).

    Returns:
        ``(H, W, 2)`` initial velocities of magnitude ``speed`` and a dict with ``channels``
        (``(H, W)`` int sink label of claimed path nodes, -1 elsewhere), ``labels`` (region of
        each node) and ``paths_ok`` (fraction of discrete paths that reached their sink).
    """
    h, w = prob.solid.shape
    n_sinks = len(prob.sink_boxes)
    free = ~prob.solid
    src_lab = -np.ones((h, w), np.int64)
    pi = prob.particles.astype(int)
    src_lab[pi[:, 1], pi[:, 0]] = prob.desired
    channels = -np.ones((h, w), np.int64)

    def potential(k: int, solve: bool = True) -> tuple[np.ndarray | None, np.ndarray]:
        # flux-driven potential flow from the sources of sink k into sink k: unit injection at
        # those sources, phi = 0 on sink k, walls (Neumann) at obstacles, the frame edge, the
        # other sinks, other sources and channels claimed by other sinks. Superharmonic, so
        # its only minimum is sink k: steepest descent from any connected node ends there.
        walls = prob.solid | ((prob.sink_id >= 0) & (prob.sink_id != k)) | ((src_lab >= 0) & (src_lab != k)) \
            | ((channels >= 0) & (channels != k) & (prob.sink_id != k))
        ok = ~walls
        dv = np.full((h, w), np.nan)
        dv[(prob.sink_id == k) & ok] = 0.0
        inj = ((src_lab == k) & ok).astype(float)
        return (_harmonic(ok, dv, inj) if solve else None), ok

    reached = 0
    tangent = np.zeros((h, w, 2))
    for k in range(n_sinks):
        mine = prob.desired == k
        if not mine.any():
            continue
        _, okk = potential(k, solve=False)
        dist, pred = _geodesic(okk, prob.sink_id == k)
        for x0, y0 in pi[mine]:
            node = y0 * w + x0
            if not np.isfinite(dist.ravel()[node]):
                continue
            for _ in range(h * w):
                i, j = divmod(node, w)
                nxt = pred[node]
                if channels[i, j] < 0 or src_lab[i, j] == k:
                    channels[i, j] = k
                    if nxt >= 0:
                        ni, nj = divmod(nxt, w)
                        tangent[i, j] = (nj - j, ni - i)
                if prob.sink_id[i, j] == k:
                    reached += 1
                    break
                node = nxt
                if node < 0:
                    break
    pots = [potential(k) for k in range(n_sinks)]
    has = channels >= 0
    if has.any():
        dch, (iy, ix) = distance_transform_edt(~has, return_indices=True)
        labels = channels[iy, ix]
    else:
        dch, iy, ix = np.full((h, w), np.inf), None, None
        labels = np.zeros((h, w), np.int64)
    labels = np.where(labels < 0, 0, labels)
    v = np.zeros((h, w, 2))
    for k, (phi, okk) in enumerate(pots):
        # fill wall nodes with a nearby valid value so gradients are one-sided there
        _, (fy, fx) = distance_transform_edt(~okk, return_indices=True)
        gy, gx = np.gradient(phi[fy, fx])
        dist, _ = _geodesic(okk, prob.sink_id == k)
        dist = np.where(np.isfinite(dist), dist, h + w)
        dy, dx = np.gradient(dist[fy, fx])
        # potential-flow direction blended with the geodesic (shortest path) direction
        a = np.stack([-gx, -gy], -1)
        a /= np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)
        g = np.stack([-dx, -dy], -1)
        g /= np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-12)
        sel = labels == k
        v[sel] = (a + g)[sel]
    # on and beside the channels: the channel's own direction (its path to the sink)
    if iy is not None:
        band = (dch <= 1.5) & (np.linalg.norm(tangent[iy, ix], axis=-1) > 0)
        v[band] = tangent[iy, ix][band]
    mag = np.linalg.norm(v, axis=-1, keepdims=True)
    v = speed * v / np.maximum(mag, 1e-12)
    v[prob.solid] = 0.0
    return v, {"channels": channels, "labels": labels, "paths_ok": reached / max(len(pi), 1)}


@dataclass
class EditResult:
    """The optimised field and its measured figures.

    Attributes:
        field: ``(H, W, 2)`` edited velocity field (nodes/frame).
        init_field: ``(H, W, 2)`` the initial field.
        exits: ``(M, 2)`` particle exit points; ``codes`` ``(M,)`` exit sink (-1 obstacle,
            -2 frame edge, -3 no exit).
        desired: ``(M,)`` desired sink per particle.
        history: objective value per accepted iteration.
        ok: False when the objective became non-finite (the field is then the last good one).
        figures: ``fraction_in_desired_sink`` (after), ``fraction_in_desired_sink_init``,
            ``E``, ``Ef``, ``Es``, ``En``, ``iterations``, ``time_s``, and the time particles
            take to reach their desired sink along the field, ``arrival_frames_median`` /
            ``arrival_frames_max`` (frames, over the particles that reach it; NaN if none).
        arrival_frames: ``(M,)`` frames each particle takes to reach the end of its trace
            (:func:`travel_frames`; ``inf``: no end within the step limit).
    """

    field: np.ndarray
    init_field: np.ndarray
    exits: np.ndarray
    codes: np.ndarray
    desired: np.ndarray
    history: list[float]
    ok: bool
    figures: dict[str, float] = field(default_factory=dict)
    arrival_frames: np.ndarray | None = None


class Objective:
    """``E(v) = alpha Ef + beta Es + gamma En`` (eq. 17) and its gradient on free nodes."""

    def __init__(self, prob: EditProblem, index: PatchIndex | None, alpha: float, beta: float, gamma: float,
                 trace_step: float = 0.5) -> None:
        self.prob = prob
        self.index = index
        self.alpha, self.beta, self.gamma = alpha, beta, gamma
        self.step = trace_step
        h, w = prob.solid.shape
        self.max_steps = int(4 * (h + w) / trace_step)

    def trace(self, v: np.ndarray, want_grad: bool = False):
        p = self.prob
        return trace_particles(v, p.particles, p.desired, p.sink_boxes, p.sink_id, p.solid,
                               self.step, self.max_steps, want_grad)

    def __call__(self, v: np.ndarray) -> tuple[float, np.ndarray, dict[str, float]]:
        m = len(self.prob.particles)
        _, codes, errs, gf = self.trace(v, True)
        self.last_fraction = fraction_in_desired_sink(codes, self.prob.desired)
        ef = float(errs.sum()) / m
        es, gs = smoothness(v)
        if self.index is not None and self.gamma > 0:
            en, gn = neighborhood(v, self.index, self.prob.offset)
        else:
            en, gn = 0.0, np.zeros_like(v)
        e = self.alpha * ef + self.beta * es + self.gamma * en
        g = self.alpha * gf / m + self.beta * gs + self.gamma * gn
        g[self.prob.fixed] = 0.0
        return e, g, {"Ef": ef, "Es": es, "En": en}


def fraction_in_desired_sink(codes: np.ndarray, desired: np.ndarray) -> float:
    """Share of particles whose exit is their desired sink."""
    return float(np.mean(codes == desired))


def optimize_field(prob: EditProblem, init: np.ndarray, index: PatchIndex | None, alpha: float = 1.0,
                   beta: float = 0.2, gamma: float = 0.2, iterations: int = 150, step: float = 0.5,
                   trace_step: float = 0.5, resume: dict[str, Any] | None = None,
                   on_iter: Callable[[int, dict[str, Any]], None] | None = None) -> EditResult:
    """Adaptive gradient descent (eq. 31-32) from ``init`` (``(H, W, 2)``).

    Each iteration moves the node with the largest gradient by ``step`` nodes/frame; the step
    grows by 1.2 after an accepted step and halves after a rejected one. A step is accepted
    when the objective decreases and the share of particles in their desired sink does not.

    Checkpointing: after every iteration ``on_iter(it, state)`` receives the whole optimiser
    state (``v`` (H,W,2), ``step``, ``it``, ``hist``); everything else is a deterministic
    function of it, so ``resume=state`` continues a killed run to the bit-identical result of
    an uninterrupted one.
    """
    t0 = time.perf_counter()
    obj = Objective(prob, index, alpha, beta, gamma, trace_step)
    v = np.array(init, dtype=np.float64)
    v[prob.fixed] = prob.fixed_value[prob.fixed]
    v0 = v.copy()
    _, codes0, _, _ = obj.trace(v)
    it = 0
    hist: list[float] = []
    if resume is not None:
        rv = np.asarray(resume["v"], dtype=np.float64)
        if rv.shape != v.shape:
            raise ValueError(f"resume state field shape {rv.shape}, expected {v.shape} (a checkpoint of another edit)")
        v, step, it, hist = rv.copy(), float(resume["step"]), int(resume["it"]), [float(x) for x in resume["hist"]]
    e, g, parts = obj(v)
    frac = obj.last_fraction
    ok = bool(np.isfinite(e) and np.isfinite(g).all())
    if not hist:
        hist = [e]
    while ok and it < iterations and step > 1e-5:
        it += 1
        gmax = np.abs(g).max()
        if gmax == 0:
            break
        vn = v - step * g / gmax
        en_, gn_, pn = obj(vn)
        if not (np.isfinite(en_) and np.isfinite(gn_).all()):
            step *= 0.5
            if on_iter is not None:
                on_iter(it, {"v": v, "step": step, "it": it, "hist": np.array(hist)})
            continue
        # accept a lower objective only if the share of particles reaching their desired sink does not
        # fall: the smoothness and neighbourhood terms may not buy their decrease with flow conservation
        if en_ < e and obj.last_fraction >= frac:
            v, e, g, parts, frac = vn, en_, gn_, pn, obj.last_fraction
            hist.append(e)
            step *= 1.2
        else:
            step *= 0.5
        if on_iter is not None:
            on_iter(it, {"v": v, "step": step, "it": it, "hist": np.array(hist)})
    exits, codes, _, _ = obj.trace(v)
    arrival = travel_frames(v, prob.particles, prob.desired, prob.sink_id, prob.solid, obj.step, obj.max_steps)
    arrived = arrival[codes == prob.desired]
    figs = {"fraction_in_desired_sink": fraction_in_desired_sink(codes, prob.desired),
            "fraction_in_desired_sink_init": fraction_in_desired_sink(codes0, prob.desired),
            "E": e, **parts, "iterations": it, "time_s": time.perf_counter() - t0,
            "n_particles": len(prob.particles),
            "arrival_frames_median": float(np.median(arrived)) if len(arrived) else float("nan"),
            "arrival_frames_max": float(arrived.max()) if len(arrived) else float("nan")}
    return EditResult(v, v0, exits, codes, prob.desired.copy(), hist, ok, figs, arrival)


def edit_field(video_field: np.ndarray, spec: EditSpec, video_fields: np.ndarray | None = None,
               init: np.ndarray | None = None, resume: dict[str, Any] | None = None,
               on_iter: Callable[[int, dict[str, Any]], None] | None = None) -> EditResult:
    """Stage driver: optimise the edited field for ``spec``.

    Args:
        video_field: ``(H, W, 2)`` the video's velocity field on the edit grid (nodes/frame),
            e.g. the time mean of the optical flow, downsampled by ``spec.downsample``.
        spec: the validated edit.
        video_fields: optional ``(F, H, W, 2)`` more video frames for the neighbourhood index.
        init: optional explicit initial field (overrides ``spec.optimizer.init``).
        resume, on_iter: checkpoint state and per-iteration callback (see :func:`optimize_field`).

    Returns:
        :class:`EditResult` with the measured figures (fraction of particles in their desired
        sink before and after, objective terms, time).
    """
    vf = np.asarray(video_field, dtype=np.float64)
    if vf.shape != (spec.height, spec.width, 2):
        raise ValueError(f"video_field shape {vf.shape}, expected {(spec.height, spec.width, 2)} (the edit grid)")
    prob = spec.rasterize(vf)
    index = PatchIndex(vf if video_fields is None else video_fields) if spec.weights.neighborhood > 0 else None
    moving = np.linalg.norm(vf, axis=-1)
    speed = float(np.median(moving[moving > 0.05 * moving.max()])) if moving.max() > 0 else 1.0
    o = spec.optimizer
    t0 = time.perf_counter()
    if init is None:
        if o.init == "harmonic":
            init, info = harmonic_init(prob, speed)
        elif o.init == "video":
            init = vf.copy()
        else:
            init = np.broadcast_to(np.array(o.uniform, float), vf.shape).copy()
    t_init = time.perf_counter() - t0
    res = optimize_field(prob, init, index, spec.weights.flow, spec.weights.smooth, spec.weights.neighborhood,
                         o.iterations, o.step, o.trace_step, resume=resume, on_iter=on_iter)
    res.figures["init_time_s"] = t_init
    return res
