"""Measured figures of a rendered edit: motion agreement, patch fidelity, flicker.

* :func:`rendered_flow_epe`: optical flow measured on the rendered frames against the edited
  field (px/frame), average endpoint error; :func:`relative_epe` divides it by the field's
  mean speed on the same mask (a frozen render scores 1; target :data:`EPE_REL_MAX`).
* :func:`patch_distance_ratio`: how close output patches are to their nearest source patch
  elsewhere (coherence) and source patches to their nearest output patch elsewhere
  (completeness), relative to how close the source's own patches are to each other elsewhere
  (taken from disjoint source frames); 1 means "as close as the source is to itself"; target
  :data:`PATCH_RATIO_MAX`.
* :func:`flicker`: mean absolute frame-to-frame change (grey levels) inside a static mask.
* :func:`compensated_flicker`: the same along the sequence's own optical flow, over the
  whole frame.
* :func:`detail_contrast`: fine-detail contrast (wash-out shows as output < source); target
  output/source >= :data:`DETAIL_RATIO_MIN`.
"""

from __future__ import annotations

import numpy as np

from vidsim.fluid.flow import endpoint_error, estimate_flow


def rendered_flow_epe(frames: np.ndarray, edited_field: np.ndarray, border: int = 8,
                      mask: np.ndarray | None = None) -> float:
    """Average endpoint error (px/frame) between the flow of ``frames`` (T,H,W,3) uint8 and
    ``edited_field`` (H,W,2) or (T-1,H,W,2), ignoring ``border`` pixels at the frame edge and,
    if given, pixels where ``mask`` (H,W) is False."""
    return float(rendered_flow_epe_frames(frames, edited_field, border, mask).mean())


def rendered_flow_epe_frames(frames: np.ndarray, edited_field: np.ndarray, border: int = 8,
                             mask: np.ndarray | None = None, flow: np.ndarray | None = None) -> np.ndarray:
    """Per frame pair: ``(T-1,)`` average endpoint error (px/frame) of the rendered frames' flow
    (estimated here unless ``flow`` gives it) against the edited field (same mask in every
    pair, so their mean is :func:`rendered_flow_epe`)."""
    fl = estimate_flow(frames) if flow is None else flow
    ef = np.broadcast_to(np.asarray(edited_field, np.float64)[-fl.shape[0]:] if np.ndim(edited_field) == 4
                         else edited_field, fl.shape)
    m = epe_mask(fl.shape[1:3], border, mask)
    return np.array([endpoint_error(fl[i], ef[i], m) for i in range(fl.shape[0])])


#: target of the rendered-flow EPE relative to the edited field's mean speed over the same mask
EPE_REL_MAX = 0.5


def epe_mask(shape: tuple[int, int], border: int = 8, mask: np.ndarray | None = None) -> np.ndarray:
    """The pixels the rendered-flow EPE is averaged over: ``(H, W)`` bool, ``border`` px from
    the frame edge excluded, and pixels where ``mask`` is False."""
    m = np.zeros(shape, bool)
    m[border:shape[0] - border, border:shape[1] - border] = True
    if mask is not None:
        m &= mask
    return m


def relative_epe(epe: float, edited_field: np.ndarray, border: int = 8,
                 mask: np.ndarray | None = None) -> tuple[float, float]:
    """``(epe / speed, speed)``: the rendered-flow EPE over the edited field's mean speed
    (px/frame) on the EPE's own mask (:func:`epe_mask`). A render that does not move (flow 0)
    scores exactly 1, one that moves against the field about 2; target :data:`EPE_REL_MAX`.
    NaN if the field does not move there."""
    f = np.asarray(edited_field, np.float64)
    m = epe_mask(f.shape[-3:-1], border, mask)
    speed = float(np.linalg.norm(f, axis=-1)[..., m].mean()) if m.any() else float("nan")
    return (epe / speed if speed > 0 else float("nan")), speed


def _patches_at(frames: np.ndarray, t: np.ndarray, y: np.ndarray, x: np.ndarray, p: int) -> np.ndarray:
    f = frames.astype(np.float32) / 255.0
    return np.stack([f[a, b:b + p, c:c + p].ravel() for a, b, c in zip(t, y, x)])


def _nn_dist(q: np.ndarray, db: np.ndarray, exclude: np.ndarray | None = None) -> np.ndarray:
    d2 = (q**2).sum(1)[:, None] - 2.0 * q @ db.T + (db**2).sum(1)[None]
    if exclude is not None:
        d2[exclude] = np.inf
    return np.sqrt(np.maximum(d2.min(1), 0.0) / db.shape[1])


#: targets of the texture figures of a rendered edit (docs/fluid_editing.md, "Measured figures")
PATCH_RATIO_MAX = 1.5
DETAIL_RATIO_MIN = 0.8


def _patch_db(frames: np.ndarray, p: int, n_frames: int = 8) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stride-2 patches of ``n_frames`` frames spread over the clip: patches, their rows,
    columns, and the frames used."""
    T, H, W, _ = frames.shape
    ts = np.unique(np.linspace(0, T - 1, min(n_frames, T)).astype(int))
    gy, gx = np.mgrid[0:H - p + 1:2, 0:W - p + 1:2]
    t = np.repeat(ts, gy.size)
    y = np.tile(gy.ravel(), len(ts))
    x = np.tile(gx.ravel(), len(ts))
    return _patches_at(frames, t, y, x, p), y, x, ts


def _overlap(qy: np.ndarray, qx: np.ndarray, y: np.ndarray, x: np.ndarray, p: int) -> np.ndarray:
    return (np.abs(qy[:, None] - y[None]) < p) & (np.abs(qx[:, None] - x[None]) < p)


def patch_distance_ratio(out_frames: np.ndarray, src_frames: np.ndarray, patch: int = 8, n_query: int = 300,
                         rng: np.random.Generator | None = None) -> dict[str, float]:
    """Bidirectional nearest-patch distance between output and source, over the source's own.

    Patches are ``patch`` x ``patch`` x 3, distances RMS per colour element in [0, 1]; a
    database holds the stride-2 patches of 8 frames spread over a clip. Every nearest
    neighbour is taken among database patches that do not overlap the query spatially (any
    frame): the distance from a piece of texture to the rest of the texture, not to itself at
    the same place (output and source share pixel coordinates: the output covers the source's
    top-left corner).

    * baseline: ``n_query`` held-out source patches (random positions in source frames outside
      the database) to the source database;
    * coherence: ``n_query`` output patches (random positions and frames) to the source
      database: does every output patch look like some source patch? Noise fails here.
    * completeness: the same held-out source patches to the output database: is every source
      patch represented somewhere in the output? A flat or washed-out output fails here (a
      low-contrast patch is close to everything in L2, so coherence alone rewards it).

    ``ratio`` = max(coherence, completeness) median over the baseline median; a copy of the
    source scores about 1, a copy placed elsewhere (texture transfer) below 1. Blur that keeps
    the patches' layout passes both directions: :func:`detail_contrast` is the wash-out check.

    Returns:
        ``ratio``, ``coherence_ratio``, ``completeness_ratio`` and the medians ``out_median``
        (coherence), ``completeness_median``, ``src_median`` (baseline).
    """
    rng = rng or np.random.default_rng(0)
    T, H, W, _ = src_frames.shape
    p = patch
    db, y_db, x_db, dbt = _patch_db(src_frames, p)
    qt_pool = np.setdiff1d(np.arange(T), dbt) if T > len(dbt) else np.arange(T)
    n = n_query
    qt = rng.choice(qt_pool, n)
    qy = rng.integers(0, H - p + 1, n)
    qx = rng.integers(0, W - p + 1, n)
    held = _patches_at(src_frames, qt, qy, qx, p)
    d_src = _nn_dist(held, db, _overlap(qy, qx, y_db, x_db, p))
    To, Ho, Wo, _ = out_frames.shape
    ot = rng.integers(0, To, n)
    oy = rng.integers(0, Ho - p + 1, n)
    ox = rng.integers(0, Wo - p + 1, n)
    d_coh = _nn_dist(_patches_at(out_frames, ot, oy, ox, p), db, _overlap(oy, ox, y_db, x_db, p))
    odb, oy_db, ox_db, _ = _patch_db(out_frames, p)
    d_comp = _nn_dist(held, odb, _overlap(qy, qx, oy_db, ox_db, p))
    base = max(float(np.median(d_src)), 1e-12)
    coh, comp = float(np.median(d_coh)) / base, float(np.median(d_comp)) / base
    return {"ratio": max(coh, comp), "coherence_ratio": coh, "completeness_ratio": comp,
            "out_median": float(np.median(d_coh)), "completeness_median": float(np.median(d_comp)),
            "src_median": float(np.median(d_src))}


MIN_STATIC_PX = 100


def flicker(frames: np.ndarray, static: np.ndarray, min_px: int = 1) -> float:
    """Mean absolute change of grey level (mean of R, G, B) between consecutive frames inside
    ``static`` (H,W); NaN if the mask has fewer than ``min_px`` pixels (not measurable)."""
    g = frames.astype(np.float64).mean(-1)
    if not static.any():
        raise ValueError("static mask is empty: no static region to measure flicker in")
    if static.sum() < min_px:
        return float("nan")
    return float(np.abs(np.diff(g, axis=0))[:, static].mean())


def static_flicker(out: np.ndarray, src: np.ndarray, field: np.ndarray, src_flow: np.ndarray,
                   solid: np.ndarray | None = None, min_px: int = MIN_STATIC_PX) -> dict[str, float]:
    """Flicker of output and source on ONE mask: the pixels static in both the edited
    ``field`` (H,W,2) and the source's time-median ``src_flow`` ((T-1,)H,W,2) (:func:`static_mask`),
    minus ``solid`` (H,W) (declared obstacles: the renderer holds their source frame, so they
    cannot flicker). ``flicker_output``/``flicker_source`` are NaN when fewer than ``min_px``
    pixels remain; ``static_fraction`` is the mask's share of the frame, ``static_fraction_output``
    / ``_source`` those of each sequence's own static region."""
    st_out = static_mask(field)
    st_src = static_mask(src_flow)
    st = st_out & st_src
    if solid is not None:
        st &= ~solid
    ok = st.sum() >= min_px
    return {"flicker_output": flicker(out, st) if ok else float("nan"),
            "flicker_source": flicker(src, st) if ok else float("nan"),
            "static_fraction": float(st.mean()), "static_fraction_output": float(st_out.mean()),
            "static_fraction_source": float(st_src.mean())}


def obstacle_grey(out: np.ndarray, src: np.ndarray, mask: np.ndarray) -> dict[str, float]:
    """Mean grey level inside the obstacles that are in the footage (``mask`` (H,W)), of the
    output and of the source, over all their frames (NaN without such obstacles). A figure, not a
    target: inside the mask the renderer draws the source's per-pixel temporal median at full
    opacity, so the two agree by construction (to the skew of the camera noise and passing fluid
    and the uint8 rounding) whatever the mask covers, even a declared disc much larger than the
    solid; it shows what the fill looks like, not whether the obstacle was declared well."""
    m = np.asarray(mask, bool)
    if not m.any():
        return {"footage_obstacle_grey_output": float("nan"), "footage_obstacle_grey_source": float("nan")}
    return {"footage_obstacle_grey_output": float(out[:, m].astype(np.float64).mean()),
            "footage_obstacle_grey_source": float(src[:, m].astype(np.float64).mean())}


def detail_contrast(frames: np.ndarray) -> float:
    """Fine-detail contrast (grey levels): the standard deviation of each frame's grey level
    minus its Gaussian blur (sigma 2 px), averaged over frames. The output's over the source's
    shows wash-out (< 1), which the patch-distance ratio does not see when the blur keeps the
    layout: a blurred output patch is close to the source's smooth patches, and a sharp source
    patch to blurred output patches elsewhere. Target: output/source >= :data:`DETAIL_RATIO_MIN`."""
    import cv2

    g = frames.astype(np.float32).mean(-1)
    return float(np.mean([np.std(x - cv2.GaussianBlur(x, (0, 0), 2.0)) for x in g]))


def compensated_flicker(frames: np.ndarray, flow: np.ndarray | None = None, border: int = 8) -> float:
    """Motion-compensated flicker (grey levels): mean over consecutive frame pairs and pixels
    (``border`` px from the edge excluded) of ``|I_n(x) - I_{n+1}(x + f_n(x))|``, ``f`` the
    sequence's own optical flow (estimated here with :func:`estimate_flow` unless given),
    ``I_{n+1}`` sampled bilinearly. The change a smooth motion does not explain: temporal
    noise, popping and cross-fades, everywhere in the frame (in static regions it is
    :func:`flicker`)."""
    import cv2

    fl = estimate_flow(frames) if flow is None else np.asarray(flow, np.float32)
    g = frames.astype(np.float32).mean(-1)
    h, w = g.shape[1:]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    res = []
    for n in range(fl.shape[0]):
        warped = cv2.remap(g[n + 1], xx + fl[n, ..., 0], yy + fl[n, ..., 1], cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_REPLICATE)
        res.append(np.abs(g[n] - warped)[border:h - border, border:w - border].mean())
    return float(np.mean(res))


def static_mask(flow: np.ndarray, threshold: float = 0.1, erode: int = 2) -> np.ndarray:
    """Pixels whose (time-median) flow speed is below ``threshold`` px/frame: ``(H, W)`` bool,
    eroded by ``erode`` pixels so that moving borders do not count. ``flow`` is (H,W,2) or
    (T,H,W,2)."""
    from scipy.ndimage import binary_erosion

    sp = np.linalg.norm(np.asarray(flow, np.float64), axis=-1)
    if sp.ndim == 3:
        sp = np.median(sp, axis=0)
    m = sp < threshold
    return binary_erosion(m, iterations=erode) if erode > 0 else m
