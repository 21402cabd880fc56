"""The estimator's skirt rig: the waistband follows the measured waist, the legs are colliders."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.cloth import mid_range_params, simulate
from vidsim.clothfit.rig import RigError, SkirtBody, skirt_model_rig
from vidsim.reality.cloth import SKIRT_SHAPE, skirt_frames, skirt_motion


def _body(T: int = 12, fps: float = 30.0) -> tuple[SkirtBody, np.ndarray]:
    t = np.arange(T) / fps
    fr = skirt_frames(skirt_motion(), t)
    return SkirtBody(fr["waist_pos"], fr["waist_rot"], fr["legs"], 0.065, **SKIRT_SHAPE), t


def test_waistband_follows_the_measured_waist_and_skirt_stays_outside_the_legs():
    body, t = _body()
    mesh, drv, t0, col = skirt_model_rig(body, t, rings=5, around=12, settle_s=0.3)
    assert t0 == pytest.approx(-0.3)
    p = mid_range_params(density=0.2).replace(stretch=300.0, bend=1e-5)
    res = simulate(mesh, p, drv, t, integrator="fast", t0=t0, colliders=col)
    assert res.ok, res.failure
    wb = mesh.tags["waistband"]
    # the waistband is exactly where the waist pose puts it, every frame
    local = mesh.rest_positions[wb] - body.waist_pos[0]
    want = body.waist_pos[:, None, :] + np.einsum("tij,nj->tni", body.waist_rot, local @ body.waist_rot[0])
    assert np.abs(res.positions[:, wb] - want).max() < 1e-6
    # the hem hangs below the waist and no vertex sinks into a leg capsule (thickness layer allowed)
    assert np.all(res.positions[:, mesh.tags["hem"], 2].max(axis=1) < body.waist_pos[:, 2] - 0.2)
    for k in range(len(t)):
        for leg in range(2):
            a, b = body.legs[k, leg]
            ab = b - a
            x = res.positions[k]
            u = np.clip((x - a) @ ab / (ab @ ab), 0, 1)
            d = np.linalg.norm(x - (a + u[:, None] * ab), axis=1)
            assert d.min() > body.leg_radius - 0.01


def test_skirt_body_round_trips_through_meta_and_rejects_bad_fields():
    body, _ = _body(5)
    again = SkirtBody.from_meta(body.to_meta(), "meta.yaml")
    assert np.allclose(again.legs, body.legs, atol=1e-6) and again.hem_radius == body.hem_radius
    bad = body.to_meta()
    bad["legs"] = bad["legs"][:3]
    with pytest.raises(RigError, match="meta.yaml: .*legs"):
        SkirtBody.from_meta(bad, "meta.yaml")
    bad = body.to_meta()
    bad["cut"]["length"] = 0.05  # shorter than the flare
    with pytest.raises(RigError, match="length"):
        SkirtBody.from_meta(bad, "meta.yaml")
    bad = body.to_meta()
    bad["waist_rot"] = (2 * np.asarray(bad["waist_rot"])).tolist()
    with pytest.raises(RigError, match="rotation"):
        SkirtBody.from_meta(bad, "meta.yaml")
    with pytest.raises(RigError, match="lacks"):
        SkirtBody.from_meta({"legs": []}, "meta.yaml")


def test_skirt_rest_bend_cone_keeps_the_cone_flat_resists_its_curvature():
    from vidsim.clothfit.rig import skirt_model_mesh

    body, _ = _body(3)
    cone, _ = skirt_model_mesh(body, 4, 12, "cone")
    flat, _ = skirt_model_mesh(body, 4, 12, "flat")
    # same start (the sewn cone), different bending rest state
    assert np.array_equal(cone.rest_positions, flat.rest_positions)
    assert np.all(flat.bend_rest == 0.0)
    # the cone's edges around the skirt are bent at rest by about 2 pi / around in total per ring
    assert np.abs(cone.bend_rest).max() > 0.2
    with pytest.raises(RigError, match="model_rest_bend = 'curved'.*cone.*flat"):
        skirt_model_mesh(body, 4, 12, "curved")
