"""Texture transfer: the rendered output moves like the edited field, its patches look like
the source (candidates from all of it, no wash-out), and static regions do not flicker more
than the source's."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.fluid.edit import EditSpec, RenderSettings
from vidsim.fluid.flow import estimate_flow
from vidsim.fluid import render as render_mod
from vidsim.fluid.metrics import (EPE_REL_MAX, compensated_flicker, detail_contrast, flicker, patch_distance_ratio,
                                  relative_epe, rendered_flow_epe, static_flicker, static_mask)
from vidsim.fluid.pipeline import obstacle_transplants, run_edit
from vidsim.fluid.render import (_N_ACC, RenderInputError, Transplant, _compose, _consistency, _splat, fine_band,
                                 obstacle_alpha, render_sequence)
from vidsim.reality.fluid import make_scene


@pytest.fixture(scope="module")
def stream():
    f = make_scene("stream_boat", size=96, n_frames=40, seed=2)
    return f.frames, estimate_flow(f.frames)


def test_advected_render_moves_with_edited_field(stream):
    frames, flow = stream
    field = flow.mean(0)
    out, figs = render_sequence(frames, flow, field, 24, np.random.default_rng(0), RenderSettings(),
                                match_flow=field)
    assert out.shape == (24, 96, 96, 3) and out.dtype == np.uint8
    epe = rendered_flow_epe(out, field, border=12)
    wrong = rendered_flow_epe(out, -field, border=12)  # the same field running backwards
    rel, speed = relative_epe(epe, field, border=12)
    # renders that do not follow the field must miss the relative target: a frozen output
    # (frame 0 repeated) and an output rendered with the field reversed
    frozen = rendered_flow_epe(np.repeat(out[:1], 8, 0), field, border=12)
    out_rev, _ = render_sequence(frames, flow, -field, 12, np.random.default_rng(0), RenderSettings(), match_flow=field)
    reversed_render = rendered_flow_epe(out_rev, field, border=12)
    print("render:", figs, "EPE", epe, "relative", rel, "speed", speed, "frozen", frozen, "reversed render",
          reversed_render)
    assert rel <= EPE_REL_MAX
    assert epe < 0.5 * wrong
    assert relative_epe(frozen, field, border=12)[0] > EPE_REL_MAX
    assert relative_epe(reversed_render, field, border=12)[0] > EPE_REL_MAX
    ratio = patch_distance_ratio(out, frames)["ratio"]
    assert ratio <= 1.5


@pytest.mark.parametrize("scene", ["waterfall", "flame"])
def test_static_flicker_not_worse_than_source(scene):
    """The video's own field rendered back: where nothing moves (the rock face, the dark
    background: thousands of static pixels) the output changes frame to frame no more than
    the footage (whose change there is camera noise)."""
    f = make_scene(scene, size=96, n_frames=40, seed=2)
    flow = estimate_flow(f.frames)
    field = flow.mean(0)
    out, _ = render_sequence(f.frames, flow, field, 24, np.random.default_rng(0), RenderSettings(), match_flow=field)
    st = static_mask(flow)
    assert st.sum() >= 1000
    fo, fs = flicker(out, st), flicker(f.frames[:24], st)
    print(scene, "static flicker output", fo, "source", fs)
    assert fo <= fs
    # the pipeline's figure: one mask for both, declared obstacles left out (here the left
    # quarter of the frame declared solid)
    solid = np.zeros(st.shape, bool)
    solid[:, :24] = True
    s = static_flicker(out, f.frames[:24], field, flow, solid)
    one = static_mask(field) & st & ~solid
    assert one.sum() >= 100 and s["static_fraction"] == pytest.approx(one.mean())
    assert s["flicker_output"] == pytest.approx(flicker(out, one))
    assert s["flicker_source"] == pytest.approx(flicker(f.frames[:24], one))


def _two_region_particles(rng: np.random.Generator, T: int = 4, H: int = 64, W: int = 96):
    """PIV-like footage in miniature: dense bright particles in the left third, sparse dim
    ones elsewhere, one uniform leftward flow whose left third is 0.004 px/frame faster (far
    below any flow's accuracy, but enough to make it every query's nearest neighbour)."""
    import cv2

    base = np.full((T, H, W), 12.0)
    for t in range(T):
        for x0, x1, n, amp in ((0, W // 3, 500, 200.0), (W // 3, W, 300, 90.0)):
            base[t, rng.integers(0, H, n), rng.integers(x0, x1, n)] += amp
    fr = np.stack([cv2.GaussianBlur(b, (0, 0), 0.7) for b in base])
    fr = np.clip(fr + rng.normal(0, 2, fr.shape), 0, 255).astype(np.uint8)
    flow = np.zeros((T - 1, H, W, 2))
    flow[..., 0] = -0.4
    flow[:, :, :W // 3, 0] -= 0.004
    return np.repeat(fr[..., None], 3, -1), flow


def test_candidates_come_from_all_of_the_source_that_matches():
    """The PIV shortfall in miniature: with the K nearest velocity patches only, every output
    patch comes from the bright third (output mean 1.6x the source's, patch ratio ~2.8); with
    candidates drawn within the flow's accuracy and uniform source use the output looks like
    the source as a whole."""
    src, flow = _two_region_particles(np.random.default_rng(3))
    field = np.zeros(src.shape[1:3] + (2,))
    field[..., 0] = -0.41
    figs = {}
    for name, kw in (("new", {}), ("k_nearest_only", {"velocity_noise": 0.0, "usage": 0.0})):
        out, _ = render_sequence(src, flow, field, 12, np.random.default_rng(0), RenderSettings(**kw),
                                 match_flow=flow.mean(0))
        figs[name] = (out.mean() / src.mean(), patch_distance_ratio(out, src)["ratio"])
    print("mean ratio, patch ratio:", figs)
    assert figs["k_nearest_only"][0] > 1.4 and figs["k_nearest_only"][1] > 1.5
    assert 0.7 <= figs["new"][0] <= 1.3 and figs["new"][1] <= 1.5


def test_colour_consistency_does_not_favour_low_contrast_patches(rng):
    existing = rng.uniform(0, 1, (8, 8, 3))
    mask = np.ones((8, 8))
    flat = np.full((8, 8, 3), existing.mean())        # the washed-out candidate
    other = rng.uniform(0, 1, (8, 8, 3))              # unrelated, same contrast
    same = existing + rng.normal(0, 0.01, existing.shape)
    l2 = [float(((c - existing) ** 2).mean()) for c in (flat, other)]
    assert l2[0] < l2[1]  # plain L2 prefers the flat patch
    e = _consistency(np.stack([flat, other, same]), existing, mask)
    assert e[2] < e[1] < e[0]


def _two_patch_accumulator(a: np.ndarray, b: np.ndarray, offset_b: float) -> np.ndarray:
    """The splat sums of two patches at weight 1/2 each, source offsets 0 and ``offset_b``."""
    acc = np.zeros(a.shape[:2] + (12,))
    for x, off in ((a, 0.0), (b, offset_b)):
        acc[..., 0:3] += 0.5 * x
        acc[..., 3:6] += 0.5 * x.mean((0, 1))
        acc[..., 6] += 0.5
        acc[..., 7] += 0.25
        acc[..., 8] += 0.5 * off
        acc[..., 11] += 0.5 * off * off
    return acc


def test_variance_blend_keeps_contrast_of_unrelated_patches_only(rng):
    """Unrelated texture (source offsets 20 px apart, correlation length 1 px) keeps its
    variance in the variance-preserving blend, where the linear blend halves it; patches with
    the same source offset (copies of one another) blend linearly."""
    a, b = rng.normal(0.5, 0.1, (2, 32, 32, 3))
    acc = _two_patch_accumulator(a, b, 20.0)
    assert _compose(acc, False, 1.0).var() == pytest.approx(0.005, rel=0.1)
    assert _compose(acc, True, 1.0).var() == pytest.approx(0.01, rel=0.1)
    acc = _two_patch_accumulator(a, a, 0.0)
    np.testing.assert_allclose(_compose(acc, True, 1.0), a, atol=1e-9)



def _splat_two(src: np.ndarray, fine: np.ndarray, where: list[tuple[float, float, float, float, float]]) -> np.ndarray:
    """:func:`_splat` of patches (12 px, overlap 4) given as (output x, y, source x, y, alpha)
    from frame 0 of ``src`` into a 40x40 accumulator."""
    acc = np.zeros((40, 40, _N_ACC))
    cx, cy, sx, sy, al = (np.array(c, float) for c in zip(*where))
    _splat(src, 12, 4, cx, cy, np.zeros(len(cx), np.int64), sx, sy, al, 0, acc, True, True, fine)
    return acc


def test_multiband_blend_of_copies_is_the_texture(rng):
    """Overlapping patches that are copies of one another (same source offset) blend to the
    source texture itself, to rounding, in the multi-band blend as in the linear one."""
    src = rng.uniform(0, 1, (1, 40, 40, 3)).astype(np.float32)
    fine = fine_band(src, 2.0)
    acc = _splat_two(src, fine, [(4, 4, 4, 4, 1.0), (12, 6, 12, 6, 1.0), (9, 13, 9, 13, 0.6)])
    covered = acc[..., 6] > 0
    assert covered.sum() > 300
    for bands in (False, True):
        np.testing.assert_allclose(_compose(acc, False, 1.0, bands)[covered], src[0][covered], atol=1e-5)


def test_multiband_blend_takes_the_fine_band_from_one_patch(rng):
    """Two unrelated patches over each other at equal weight: the linear blend halves the fine
    band's variance; the multi-band blend shows the coarse bands' mean plus the fine band of the
    first (older) patch, exactly, so the fine variance is the source's."""
    src = rng.uniform(0, 1, (1, 40, 40, 3)).astype(np.float32)
    fine = fine_band(src, 2.0)
    acc = _splat_two(src, fine, [(10, 10, 2, 3, 0.5), (10, 10, 25, 26, 0.5)])
    core = np.s_[14:18, 14:18]  # inside both patches' full-weight parts
    a, b = src[0, 7:11, 6:10], src[0, 30:34, 29:33]
    fa, fb = fine[0, 7:11, 6:10], fine[0, 30:34, 29:33]
    np.testing.assert_allclose(_compose(acc, False, 1.0)[core], (a + b) / 2, atol=1e-5)
    np.testing.assert_allclose(_compose(acc, False, 1.0, True)[core], (a - fa + b - fb) / 2 + fa, atol=1e-5)


def test_multiband_fine_band_is_the_largest_weight_patchs(rng):
    """The fine band at a pixel is that of the patch with the largest weight there, whichever
    came first: an older faint patch under a newer strong one (alpha 0.3 then 0.9), and two
    offset patches, each owning the pixels where its feather weighs more than the other's."""
    src = rng.uniform(0, 1, (1, 40, 40, 3)).astype(np.float32)
    fine = fine_band(src, 2.0)
    for pair in ([(12, 12, 3, 4, 0.3), (12, 12, 24, 25, 0.9)], [(10, 12, 3, 4, 1.0), (17, 13, 24, 25, 1.0)]):
        one = [_splat_two(src, fine, [q]) for q in pair]
        both = _splat_two(src, fine, pair)
        wa, wb = one[0][..., 6], one[1][..., 6]
        overlap = (wa > 0) & (wb > 0) & (wa != wb)
        assert overlap.sum() > 20
        own_b = wb > wa
        assert own_b[overlap].any() and (pair[0][4] == 0.3 or (~own_b)[overlap].any())
        fa = one[0][..., 12:15] / np.maximum(wa, 1e-12)[..., None]  # each patch's sampled fine band
        fb = one[1][..., 12:15] / np.maximum(wb, 1e-12)[..., None]
        coarse = (both[..., 0:3] - both[..., 12:15]) / np.maximum(wa + wb, 1e-12)[..., None]
        want = coarse + np.where(own_b[..., None], fb, fa)
        np.testing.assert_allclose(_compose(both, False, 1.0, True)[overlap], want[overlap], atol=1e-5)


def test_a_misspelt_blend_is_refused_by_name():
    f = make_scene("stream_boat", size=32, n_frames=6, seed=0)
    flow = np.zeros((5, *f.frames.shape[1:3], 2))
    for key, bad in (("blend", "multi-band"), ("resample", "nearest"), ("mode", "advect")):
        with pytest.raises(RenderInputError, match=f"render.{key}='{bad}'"):
            render_sequence(f.frames, flow, np.zeros((*f.frames.shape[1:3], 2)), 2, np.random.default_rng(0),
                            RenderSettings(**{key: bad}))


@pytest.fixture(scope="module")
def translating():
    """A stochastic texture (white noise blurred by 1 px) translating right by 1 px/frame, with
    its exact flow: 40 frames of 64x64."""
    import cv2
    r = np.random.default_rng(0)
    T, H, W = 40, 64, 64
    big = cv2.GaussianBlur(r.normal(0, 1, (H, W + T + 8)).astype(np.float32), (0, 0), 1.0)
    big = np.clip(128 + 60 * big / big.std(), 0, 255)
    frames = np.stack([np.repeat(big[:, T - t:T - t + W, None], 3, -1) for t in range(T)]).astype(np.uint8)
    flow = np.zeros((T - 1, H, W, 2))
    flow[..., 0] = 1.0
    return frames, flow


def test_multiband_keeps_fine_contrast_of_a_translated_texture(translating):
    """The texture translated by the uniform flow it moves with in the footage, 30 frames: the
    multi-band render keeps the fine-detail contrast (:func:`detail_contrast`) within 5 % of
    the source's in every frame checked (0.99 / 0.98 / 0.99 at seed 0); the linear feather
    loses 10-16 % (0.90 / 0.88 / 0.84): overlapping unrelated patches averaged."""
    frames, flow = translating
    field = flow[0]
    ref = detail_contrast(frames[:1])
    ratios = {}
    for blend in ("linear", "multiband"):
        out, figs = render_sequence(frames, flow, field, 30, np.random.default_rng(0), RenderSettings(blend=blend),
                                    match_flow=field)
        assert figs["bare_pixels"] == 0
        ratios[blend] = np.array([detail_contrast(out[i:i + 1]) / ref for i in (0, 10, 29)])
    print("detail ratio per frame", ratios)
    assert np.all(np.abs(ratios["multiband"] - 1.0) < 0.05)
    assert np.all(ratios["linear"] < 0.93)

def test_inflow_edge_is_covered(stream):
    """Patches leaving the inflow edge are replaced before a bare (black) strip opens."""
    frames, flow = stream
    field = np.zeros(frames.shape[1:3] + (2,))
    field[..., 0] = 0.6  # everything moves right: the left edge is an inflow
    out, _ = render_sequence(frames, flow, field, 24, np.random.default_rng(0), RenderSettings(), match_flow=field)
    assert frames.max(-1).min() > 0
    bare = (out.max(-1) == 0).sum((1, 2))
    print("bare pixels per frame", bare)
    assert bare.max() <= 4


def test_no_pixel_outside_the_fill_is_left_bare(stream):
    """A vortex around the footage's boat (declared in the footage) opens holes where patches
    overlap, between the cells' own parts: the hole filler checked only a cell's own part (its
    patch minus the overlaps) and left 21 bare, black pixels over 24 frames at seed 0 (5 Dec 2026).
    Every pixel outside the boat's fill must be covered by a patch."""
    frames, flow = stream
    boat = make_scene("stream_boat", size=96, n_frames=40, seed=2).solid
    yy, xx = np.mgrid[0:96, 0:96] - 47.5
    field = np.stack([-0.03 * yy, 0.03 * xx], -1)  # rotation about the centre, up to 2 px/frame
    field[boat] = 0.0
    out, figs = render_sequence(frames, flow, field, 24, np.random.default_rng(0), RenderSettings(), solid=boat,
                                match_flow=field, footage_solid=boat)
    assert frames.max(-1).min() > 0  # the footage has no black pixel: black is bare
    black = out.max(-1) == 0
    print("black pixels per frame", black.sum((1, 2)), "bare", figs["bare_pixels"], "before the last pass",
          figs["bare_before_last_pass"])
    assert black.sum() == 0 and figs["bare_pixels"] == 0
    # the cells' own rule (the whole window) covers them, not only the last pass (which would leave
    # 0 black pixels here too: without the whole-window rule 13 pixels reach it, a review measured)
    assert figs["bare_before_last_pass"] == 0 and figs["spawned_on_bare"] == 0


def test_compensated_flicker_ignores_motion_and_sees_noise(rng):
    import cv2

    tex = cv2.GaussianBlur(rng.uniform(0, 255, (64, 80)).astype(np.float32), (0, 0), 2.0)
    moving = np.stack([np.roll(tex, k, axis=1) for k in range(8)])
    clean = np.repeat(np.clip(moving, 0, 255).astype(np.uint8)[..., None], 3, -1)
    noisy = np.clip(clean + rng.normal(0, 4, clean.shape[:3])[..., None], 0, 255).astype(np.uint8)
    assert compensated_flicker(clean) < 0.5
    assert flicker(clean, np.ones((64, 80), bool)) > 2.0  # plain differences see the motion
    assert 3.0 < compensated_flicker(noisy) < 7.0  # |N(0, 4 sqrt 2)| has mean 4.5


def test_run_edit_second_boat(stream):
    frames, flow = stream
    spec = EditSpec.from_dict({
        "grid": {"height": 48, "width": 48}, "downsample": 2,
        "sources": [{"box": [0, 2, 1, 46], "distribution": "out"}],
        "sinks": [{"name": "out", "box": [47, 1, 48, 47]}],
        "obstacles": [{"center": [18.0, 24.0], "radii": [6.0, 2.7], "in_footage": True},
                      {"center": [34.0, 13.0], "radii": [5.0, 2.2]}],
        "optimizer": {"iterations": 30}, "render": {"frames": 16}})
    r = run_edit(frames, spec, np.random.default_rng(1), flow=flow)
    f = r["figures"]
    print("second boat:", f)
    assert f["edit"]["fraction_in_desired_sink"] >= 0.98
    assert f["rendered_flow_epe_rel"] <= EPE_REL_MAX
    assert f["rendered_flow_epe_rel"] == pytest.approx(f["rendered_flow_epe_px"] / f["edited_speed_epe_mask_px"])
    assert r["frames"].shape == (16, 96, 96, 3)
    # the footage's boat shows the footage's pixels (its temporal median: a check that the fill is
    # wired in, not a quality figure, which the report gives without a verdict)
    assert abs(f["footage_obstacle_grey_output"] - f["footage_obstacle_grey_source"]) <= 1.0
    assert "footage_obstacle_grey_diff_max" not in f
    # the added boat is drawn as the footage's (flat-coloured) boat, mapped onto its ellipse
    assert f["render"]["transplanted_obstacles"] == 1
    yy, xx = np.mgrid[0:96, 0:96]
    core = ((xx - 68.5) / 9.0) ** 2 + ((yy - 26.5) / 3.4) ** 2 <= 1  # 1 px in from its 11 x 5.4 px half-sizes
    boat = r["frames"][:, core].astype(np.float64).mean(-1)
    print("added boat grey", boat.mean(), boat.std(), "footage boat", frames[:, 48, 36].mean(-1).mean())
    assert abs(boat.mean() - 70.0) <= 2.0 and boat.std() <= 2.0  # boat colour (120, 60, 30)
    # static flicker on one mask: here the only static pixels are the boats, declared obstacles,
    # so it is not measurable (each sequence's own static region held boats: output the two
    # declared ones, source the footage's boat)
    assert f["static_fraction_output"] > 0.01 and f["static_fraction_source"] > 0
    assert f["static_fraction"] < 100 / 96**2
    assert np.isnan(f["flicker_output"]) and np.isnan(f["flicker_source"])


def test_bad_render_input(stream):
    frames, flow = stream
    with pytest.raises(RenderInputError, match="src_flow shape"):
        render_sequence(frames, flow[:-1], flow[0], 2, np.random.default_rng(0))


RED = (210, 40, 30)


def _still_red_disc(T: int = 20, H: int = 48, W: int = 64, colour=RED):
    """A blue-grey texture (red channel below its green everywhere, grey 73-167) moving right 1
    px/frame past a still disc of ``colour`` (centre pixel (40, 24), radius 8 px), camera noise
    sigma 2 grey levels on both: any red seen outside a red disc came from the disc."""
    import cv2

    rng = np.random.default_rng(3)
    tex = cv2.GaussianBlur(rng.uniform(0, 1, (H, W + T)), (0, 0), 1.5)
    tex = (tex - tex.min()) / np.ptp(tex)
    fluid = np.stack([20 + 40 * tex, 80 + 120 * tex, 120 + 120 * tex], -1)
    yy, xx = np.mgrid[0:H, 0:W]
    disc = (xx - 40) ** 2 + (yy - 24) ** 2 <= 8**2
    fr = []
    for t in range(T):
        f = fluid[:, T - t:T - t + W].copy()
        f[disc] = colour
        fr.append(f + rng.normal(0, 2, f.shape))
    return np.clip(np.stack(fr), 0, 255).round().astype(np.uint8), disc


@pytest.fixture(scope="module")
def red_disc():
    frames, disc = _still_red_disc()
    return frames, disc, estimate_flow(frames)


def _render_with_disc(frames, disc, flow, added, footage: bool, monkeypatch=None, transplants=()):
    """Render the texture flowing right at 0.5 px/frame, zero on the obstacles (the footage's disc
    and ``added``); returns the output and the selector's picks (pool, (t, y, x))."""
    field = np.zeros(disc.shape + (2,))
    field[..., 0] = 0.5
    field[disc | added] = 0.0
    picks = []
    if monkeypatch is not None:
        select = render_mod.PatchSelector.select

        def spy(self, *a, pool="fluid", **k):
            r = select(self, *a, pool=pool, **k)
            picks.append((pool, r[0]))
            return r
        monkeypatch.setattr(render_mod.PatchSelector, "select", spy)
    s = RenderSettings(patch=8, overlap=2)
    out, figs = render_sequence(frames, flow, field, 16, np.random.default_rng(0), s, solid=disc | added,
                                match_flow=flow.mean(0), footage_solid=disc if footage else None,
                                transplants=transplants)
    return out, picks, figs


def test_obstacle_in_footage_shows_the_footage(red_disc, monkeypatch):
    """A still obstacle declared in the footage renders as the footage's own pixels: the per-pixel
    temporal median of the source, so within 0.5 grey level of it (the uint8 rounding: with an
    even number of frames the median is a half-integer) and within the range the source's own
    frames take at that pixel; no fluid patch is taken from what the fill shows (the disc and its
    blend ring), and no red reaches the fluid. Declared as a plain obstacle, as before this fix,
    patches next to it take the disc's red into the fluid."""
    frames, disc, flow = red_disc
    yy, xx = np.mgrid[0:disc.shape[0], 0:disc.shape[1]]
    added = (xx - 14) ** 2 + (yy - 24) ** 2 <= 6**2  # an obstacle the edit adds where the footage is fluid
    out, picks, figs = _render_with_disc(frames, disc, flow, added, True, monkeypatch)
    med = np.median(frames.astype(np.float64), axis=0)
    inside = out[:, disc].astype(np.float64)
    print("in the disc: max |output - source median|", np.abs(inside - med[disc]).max(), figs)
    assert np.abs(inside - med[disc]).max() <= 0.5
    assert np.all(inside >= frames[:, disc].min(0)) and np.all(inside <= frames[:, disc].max(0))
    # the fill's ring: between the fill and the fluid, no seam (a monotone ramp to 0 over 2 px)
    a = obstacle_alpha(disc, 2)
    assert a[disc].min() == 1.0 and 0 < a[~disc].max() < 1 and np.all(a[~disc] < 1)
    shown = a > 0
    p = 8
    fluid = [(t, y, x) for pool, (t, y, x) in picks if pool == "fluid"]
    assert len(fluid) > 20
    assert not any(shown[y:y + p, x:x + p].any() for t, y, x in fluid)
    # no red in the fluid (away from the added obstacle, which shows red on purpose, and its patches)
    far = ~shown & ~(obstacle_alpha(added, p) > 0)
    r, g = out[..., 0].astype(int), out[..., 1].astype(int)
    print("red px in the fluid", int((r > g)[:, far].sum()))
    assert not np.any((r > g)[:, far])
    # the added obstacle takes solid texture: windows centred on the footage's disc (red)
    solid = [(y, x) for pool, (t, y, x) in picks if pool == "solid"]
    assert solid and all(disc[y + p // 2, x + p // 2] for y, x in solid)
    assert out[:, added, 0].mean() > out[:, added, 1].mean()
    # before: the disc a plain obstacle, its pixels velocity-matched patches, red in the fluid
    old, _, _ = _render_with_disc(frames, disc, flow, added, False)
    ro, go = old[..., 0].astype(int), old[..., 1].astype(int)
    print("before: red px in the fluid", int((ro > go)[:, far].sum()),
          "max |output - median| in the disc", np.abs(old[:, disc] - med[disc]).max())
    assert np.any((ro > go)[:, far])


@pytest.fixture(scope="module")
def dark_disc():
    frames, disc = _still_red_disc(colour=(10, 10, 10))
    return frames, disc, estimate_flow(frames)


def test_added_obstacle_is_drawn_as_the_footage_obstacle(dark_disc, monkeypatch):
    """An added disc (centre (14, 24), radius 6 px) transplanted from the footage's dark disc
    (centre (40, 24), radius 8 px, grey 10): dark over its whole shape and nowhere else, in every
    frame: 1 px in from its outline grey < 20, 2-8 px outside it (past the fill's 2 px ramp) the
    fluid (grey >= 73) shows; no patch is spawned centred in it. (On the outline itself the two
    pixel discs are not exact scaled copies: a rim pixel may sample the footage disc's rim.)
    From patches (``transplants`` empty, as before) it is blocky: dark squares reach past its
    outline or fluid shows inside it."""
    frames, disc, flow = dark_disc
    yy, xx = np.mgrid[0:disc.shape[0], 0:disc.shape[1]]
    added = (xx - 14) ** 2 + (yy - 24) ** 2 <= 6**2
    d_out = np.hypot(xx - 14, yy - 24) - 6  # distance outside the added disc's outline (px)
    inside = d_out <= -1
    centres = []
    append = render_mod._Patches.append

    def spy(self, cx, cy, *a, **k):
        centres.append((cy + 4, cx + 4))  # patch 8: its centre pixel
        return append(self, cx, cy, *a, **k)
    monkeypatch.setattr(render_mod._Patches, "append", spy)
    tp = Transplant(added, (14.0, 24.0), (40.0, 24.0), (8 / 6, 8 / 6))
    out, _, figs = _render_with_disc(frames, disc, flow, added, True, transplants=[tp])
    g = out.astype(np.float64).mean(-1)
    ring = (d_out >= 2) & (d_out <= 8)
    print("transplant: inside max", g[:, inside].max(), "ring 2-8 px out min", g[:, ring].min(), figs)
    assert figs["transplanted_obstacles"] == 1
    assert g[:, inside].max() < 20 and g[:, ring].min() > 40
    assert centres and not any(added[int(y), int(x)] for y, x in centres
                               if 0 <= y < added.shape[0] and 0 <= x < added.shape[1])
    # before: drawn from patches (solid texture from windows centred on the footage's disc)
    old, _, _ = _render_with_disc(frames, disc, flow, added, True)
    go = old.astype(np.float64).mean(-1)
    print("patches: inside max", go[:, inside].max(), "ring 2-8 px out min", go[:, ring].min())
    assert go[:, inside].max() >= 20 or go[:, ring].min() <= 40


def test_transplant_maps_an_ellipse_onto_one_of_other_radii():
    """The affine map between two declared ellipses of different radii (nodes of 2 px): centres
    at pixel ``n ds + (ds - 1) / 2``, scale the ratio of the half-sizes ``(r + 1/2) ds``. A
    footage image holding the footage ellipse's area (half-sizes 17.6 x 8 px), transplanted,
    covers the added ellipse's (11 x 5 px): IoU >= 0.95, centroid within 0.25 px, extent within
    1 px per axis; the translation alone (scale 1) does not fit."""
    spec = EditSpec.from_dict({
        "grid": {"height": 40, "width": 48}, "downsample": 2,
        "sources": [{"box": [0, 2, 1, 38], "distribution": "out"}], "sinks": [{"name": "out", "box": [47, 1, 48, 39]}],
        "obstacles": [{"center": [30.0, 12.0], "radii": [8.3, 3.5], "in_footage": True},
                      {"center": [14.0, 28.0], "radii": [5.0, 2.0]}]})
    H, W = 80, 96
    (tp,) = obstacle_transplants(spec, (H, W))
    assert tp.center == (28.5, 56.5) and tp.src_center == (60.5, 24.5)
    assert tp.scale == pytest.approx((8.8 / 5.5, 4.0 / 2.5))
    assert tp.mask.shape == (H, W) and tp.mask[56, 28] and tp.mask.sum() == 31 * 4  # its 31 nodes
    yy, xx = np.mgrid[0:H, 0:W]
    src = ((xx - 60.5) / 17.6) ** 2 + ((yy - 24.5) / 8.0) ** 2 <= 1
    want = ((xx - 28.5) / 11.0) ** 2 + ((yy - 56.5) / 5.0) ** 2 <= 1
    med = np.repeat(src[..., None], 3, -1).astype(np.float32)  # the footage: 1 on its ellipse

    def fit(t):
        m = t.image(med, (H, W))[..., 0] > 0.5
        iou = (m & want).sum() / (m | want).sum()
        (y, x), (ty, tx) = np.argwhere(m).mean(0), np.argwhere(want).mean(0)
        ext = np.ptp(np.argwhere(m), 0) - np.ptp(np.argwhere(want), 0)
        return iou, np.hypot(y - ty, x - tx), np.abs(ext).max()
    iou, off, ext = fit(tp)
    shifted = fit(Transplant(tp.mask, tp.center, tp.src_center, (1.0, 1.0)))
    print("IoU", iou, "centroid offset px", off, "extent px", ext, "translation only:", shifted)
    assert iou >= 0.95 and off <= 0.25 and ext <= 1
    assert shifted[0] < 0.7


def test_added_obstacles_fall_back_to_patches(stream, monkeypatch):
    """What ``run_edit`` hands the renderer: a transplant for the added boat when the footage's
    boat is declared ``in_footage``; none (patches, as before) without an ``in_footage``
    obstacle or with ``render.added_obstacles: patches``."""
    import vidsim.fluid.pipeline as pipeline_mod

    frames, flow = stream
    seen = []

    class Stop(Exception):
        pass

    def fake_render(*a, transplants=(), **k):
        seen.append(list(transplants))
        raise Stop
    monkeypatch.setattr(pipeline_mod, "render_sequence", fake_render)
    footage = {"center": [18.0, 24.0], "radii": [6.0, 2.7], "in_footage": True}
    added = {"center": [34.0, 13.0], "radii": [5.0, 2.2]}
    for obstacles, render in (([footage, added], {}), ([added], {}), ([footage, added], {"added_obstacles": "patches"})):
        spec = EditSpec.from_dict({
            "grid": {"height": 48, "width": 48}, "downsample": 2,
            "sources": [{"box": [0, 2, 1, 46], "distribution": "out"}], "sinks": [{"name": "out", "box": [47, 1, 48, 47]}],
            "obstacles": obstacles, "optimizer": {"iterations": 0}, "render": {"frames": 2, **render}})
        with pytest.raises(Stop):
            run_edit(frames, spec, np.random.default_rng(0), flow=flow)
    assert [len(t) for t in seen] == [1, 0, 0]
    assert seen[0][0].src_center == (36.5, 48.5) and seen[0][0].center == (68.5, 26.5)


def test_a_diverged_optimisation_stops_before_the_render(stream, monkeypatch):
    """An edit whose optimisation became non-finite is refused with its iteration count before
    the render starts (the stage rendered and measured every frame first until 6 Dec 2026)."""
    import types

    import vidsim.fluid.pipeline as pipeline_mod
    from vidsim.fluid.edit import EditSpecError

    frames, flow = stream
    monkeypatch.setattr(pipeline_mod, "edit_field",
                        lambda *a, **k: types.SimpleNamespace(ok=False, figures={"iterations": 3}))
    rendered = []
    monkeypatch.setattr(pipeline_mod, "render_sequence", lambda *a, **k: rendered.append(1))
    spec = EditSpec.from_dict({
        "grid": {"height": 48, "width": 48}, "downsample": 2,
        "sources": [{"box": [0, 2, 1, 46], "distribution": "out"}], "sinks": [{"name": "out", "box": [47, 1, 48, 47]}],
        "render": {"frames": 2}})
    with pytest.raises(EditSpecError, match=r"non-finite .* after 3 iterations"):
        run_edit(frames, spec, np.random.default_rng(0), flow=flow)
    assert rendered == []


def test_an_added_obstacle_overlapping_the_footage_one_leaves_it_dark(dark_disc):
    """An added disc (centre (50, 24), radius 6 px) overlapping the footage's dark disc (centre
    (40, 24), radius 8 px): the added disc's blend ring must not lay the source's surroundings over
    the footage disc, which stays dark everywhere (review, 5 Dec 2026: a band of grey 36-84 at
    x = 42-43 inside it)."""
    frames, disc, flow = dark_disc
    yy, xx = np.mgrid[0:disc.shape[0], 0:disc.shape[1]]
    added = (xx - 50) ** 2 + (yy - 24) ** 2 <= 6**2
    tp = Transplant(added, (50.0, 24.0), (40.0, 24.0), (8 / 6, 8 / 6))
    out, _, _ = _render_with_disc(frames, disc, flow, added, True, transplants=[tp])
    g = out.astype(np.float64).mean(-1)
    core = (np.hypot(xx - 40, yy - 24) <= 7) & ~added  # the footage disc 1 px in from its outline
    assert g[:, core].max() < 20, g[:, core].max()


def test_a_small_added_obstacle_leaves_no_bare_pixels():
    """With a small overlap (16 px patches, 2 px overlap) a transplanted disc of radius 3 px does
    not cover its cell's own part: that cell still gets a patch, so no pixel is left black
    (review, 5 Dec 2026: 698 black pixels over 16 frames)."""
    frames, disc = _still_red_disc(colour=(10, 10, 10))
    flow = estimate_flow(frames)
    yy, xx = np.mgrid[0:disc.shape[0], 0:disc.shape[1]]
    added = (xx - 20) ** 2 + (yy - 20) ** 2 <= 3**2  # on a cell's centre pixel (cells of 14 px from -2)
    tp = Transplant(added, (20.0, 20.0), (40.0, 24.0), (8 / 3, 8 / 3))
    field = np.zeros(disc.shape + (2,))
    field[..., 0] = 0.5
    field[disc | added] = 0.0
    out, _ = render_sequence(frames, flow, field, 16, np.random.default_rng(0), RenderSettings(patch=16, overlap=2),
                             solid=disc | added, match_flow=flow.mean(0), footage_solid=disc, transplants=[tp])
    black = (out.max(-1) == 0)
    assert black.sum() == 0, black.sum()


def test_a_pixel_only_transplanted_obstacles_cells_reach_gets_a_patch():
    """Two transplanted boxes 6 px apart (16 px patches, 2 px overlap): the two cells centred in
    them take no patch, their fills cover their own parts, and the gap between these lies in no
    other cell's window and outside both fills' ramps, so no cell takes it (24 black pixels per
    frame). The hole filler's last pass spawns a patch centred on such a pixel."""
    frames, disc = _still_red_disc(colour=(10, 10, 10))
    flow = estimate_flow(frames)
    yy, xx = np.mgrid[0:disc.shape[0], 0:disc.shape[1]]
    boxes = [(yy >= 15) & (yy <= 24) & (xx >= x0) & (xx <= x1) for x0, x1 in ((15, 23), (30, 38))]  # cells of 14 px from -2
    tps = [Transplant(m, (float(xx[m].mean()), 19.5), (40.0, 24.0), (8 / 5, 8 / 5)) for m in boxes]
    field = np.zeros(disc.shape + (2,))
    field[..., 0] = 0.5
    field[boxes[0] | boxes[1]] = 0.0
    out, figs = render_sequence(frames, flow, field, 8, np.random.default_rng(0), RenderSettings(patch=16, overlap=2),
                                solid=boxes[0] | boxes[1], match_flow=flow.mean(0), transplants=tps)
    black = (out.max(-1) == 0).sum((1, 2))
    assert black.sum() == 0, black
    print("patches on bare pixels", figs["spawned_on_bare"])
    assert figs["bare_pixels"] == 0 and figs["spawned_on_bare"] > 0
