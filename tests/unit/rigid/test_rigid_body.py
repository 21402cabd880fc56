"""meta.yaml's body description is checked before any fit: non-finite or non-physical values and
symmetries that are not symmetries were accepted and gave silent wrong fits (review, rigid input
checks): NaN centres ended the fit at the guess, a symmetry list without the identity made an
orientation differ from itself by 180 degrees and reported false "equally good" solutions."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.rigid.body import BoxBody, RigidBodyError, t_object
from vidsim.rigid.dynamics import quat_exp, quat_to_rot
from vidsim.rigid.fit import Candidate, distinct_alternatives, orientation_error_deg

T, _ = t_object()
META = T.to_meta()
HALF_TURN_Y = np.diag([-1.0, 1.0, -1.0])  # the T's own symmetry (about its stem axis)


@pytest.mark.parametrize("field, value, match", [
    ("centers", [[np.nan, 0, 0], [0, -0.15, 0]], r"'centers' must be finite numbers, got \[\[nan"),
    ("half_sizes", [[0.15, np.inf, 0.03], [0.03, 0.12, 0.03]], r"'half_sizes' must be finite numbers, got .*inf"),
    ("inertia", [[np.nan, 0, 0], [0, 1e-3, 0], [0, 0, 1e-3]], r"'inertia' must be finite numbers, got \[\[nan"),
    ("inertia", [[np.inf, 0, 0], [0, 1e-3, 0], [0, 0, 1e-3]], r"'inertia' must be finite numbers, got \[\[inf"),
    ("inertia", [[1e-3, 0, 0], [0, 1e-3, 0], [0, 0, 5e-3]], r"'inertia' is not the inertia of any rigid body.*I3 <= I1 \+ I2"),
    ("symmetries", [[[1, 0, 0], [0, 1, 0], [0, 0, np.nan]]], r"'symmetries' must be finite numbers"),
])
def test_non_finite_and_non_physical_body_fields_are_named(field, value, match):
    with pytest.raises(RigidBodyError, match=r"meta\.object: body: " + match):
        BoxBody.from_meta({**META, field: value})


def test_inertia_triangle_inequality_allows_a_thin_plate_and_rounding():
    # a flat plate lies on the bound I3 = I1 + I2; values rounded to 4 digits stay accepted
    BoxBody.from_meta({**META, "inertia": [[1e-3, 0, 0], [0, 2e-3, 0], [0, 0, 3.0009e-3]]})
    with pytest.raises(RigidBodyError, match="inertia"):
        BoxBody.from_meta({**META, "inertia": [[1e-3, 0, 0], [0, 2e-3, 0], [0, 0, 3.01e-3]]})


def test_symmetries_without_the_identity_get_it_first():
    b = BoxBody.from_meta({**META, "symmetries": [HALF_TURN_Y.tolist()]})
    assert b.symmetries.shape == (2, 3, 3)
    assert np.array_equal(b.symmetries[0], np.eye(3)) and np.array_equal(b.symmetries[1], HALF_TURN_Y)
    # the identity given last is moved to the front, not duplicated
    b2 = BoxBody.from_meta({**META, "symmetries": [HALF_TURN_Y.tolist(), np.eye(3).tolist()]})
    assert np.array_equal(b2.symmetries, b.symmetries)
    # none given: the identity alone
    assert np.array_equal(BoxBody(T.centers, T.half_sizes, T.mass, T.inertia, []).symmetries, np.eye(3)[None])
    # consequences: an orientation is 0 degrees from itself; an identical copy is no "distinct" solution
    q = quat_exp(np.array([0.2, 0.4, -0.1]))
    assert orientation_error_deg(quat_to_rot(q), quat_to_rot(q), b.symmetries) == pytest.approx(0.0, abs=1e-5)
    p = np.r_[0.0, 0.5, 3.0, 0, 0, 0, 0.3, -5.0, 0.1, 1.0, 2.0, 0.5, 0.0, 0.0]
    best = Candidate(p, q, 1.0, 0.98, np.ones(10), [], 0)
    same = Candidate(p.copy(), q.copy(), 1.0, 0.98, np.ones(10), [], 1)
    assert distinct_alternatives(best, [same], b, np.linspace(0, 1, 10), 0.0) == []


@pytest.mark.parametrize("sym, match", [
    (np.diag([2.0, 1.0, 1.0]), r"'symmetries\[1\]' = .* is not a proper rotation.*det = 2"),
    (-np.eye(3), r"'symmetries\[1\]' = .* is not a proper rotation.*det = -1"),  # a reflection
    (np.diag([1.0, -1.0, -1.0]), r"'symmetries\[1\]' = .* does not map the boxes onto themselves"),  # half turn about x
])
def test_symmetries_that_are_not_rotations_of_the_shape_are_named(sym, match):
    with pytest.raises(RigidBodyError, match=r"meta\.object: body: " + match):
        BoxBody.from_meta({**META, "symmetries": [np.eye(3).tolist(), sym.tolist()]})
