"""Scoring of a rigid-body estimate against the truth of a synthetic throw (evaluation only).

Nothing here is called by an estimator: these functions read the truth to perturb it into an
initial guess (the protocol of the issue) and to score the result.
"""

from __future__ import annotations

import numpy as np

from vidsim.rigid.body import BoxBody
from vidsim.rigid.dynamics import gravity_angles, gravity_vector, quat_exp, quat_mul, quat_to_rot
from vidsim.rigid.fit import FitResult, orientation_error_deg

CRITERIA = {"orientation_deg": 5.0, "omega_rel": 0.05, "position_rel_range": 0.01, "velocity_rel": 0.02,
            "gravity_deg": 1.0, "mean_iou": 0.97}
"""Success thresholds of the issue (orientation modulo symmetry, relative errors, IoU)."""


def _unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def perturbed_guess(truth: dict, rng: np.random.Generator, orient_deg: float = 30.0, omega_rel: float = 0.3,
                    vel_rel: float = 0.2, pos_m: float = 0.1, grav_deg: float = 10.0) -> dict:
    """An initial guess at the stated distances from the truth, in random directions."""
    q = quat_mul(np.asarray(truth["quaternion"], float), quat_exp(_unit(rng) * np.radians(orient_deg)))
    w = np.asarray(truth["omega_world"], float)
    v = np.asarray(truth["velocity"], float)
    g = gravity_vector(truth["tilt"], truth["roll"])
    axis = np.cross(g, _unit(rng))
    axis /= np.linalg.norm(axis)
    g2 = quat_to_rot(quat_exp(axis * np.radians(grav_deg))) @ g
    tilt, roll = gravity_angles(g2)
    return {"position": (np.asarray(truth["position"]) + pos_m * _unit(rng)).tolist(), "quaternion": q.tolist(),
            "velocity": (v + vel_rel * np.linalg.norm(v) * _unit(rng)).tolist(),
            "omega_world": (w + omega_rel * np.linalg.norm(w) * _unit(rng)).tolist(),
            "tilt": tilt, "roll": roll, "t0": truth["t0"]}


def score(res: FitResult, truth: dict, body: BoxBody, iou_truth: np.ndarray | None = None) -> dict:
    """Errors of an estimate and whether each criterion of :data:`CRITERIA` is met.

    Args:
        res: the estimate (its ``t0`` must equal the truth's).
        truth: the truth dictionary of the throw.
        body: the body (for its symmetries).
        iou_truth: optional per-frame IoU of the fit against ground-truth masks; when given the
            IoU criterion uses it, otherwise the IoU against the footage silhouettes.
    """
    X = np.asarray(truth["position"], float)
    V = np.asarray(truth["velocity"], float)
    W = np.asarray(truth["omega_world"], float)
    g = gravity_vector(truth["tilt"], truth["roll"])
    ge = gravity_vector(res.params[12], res.params[13])
    e = {
        "orientation_deg": orientation_error_deg(quat_to_rot(res.q0), quat_to_rot(np.asarray(truth["quaternion"])),
                                                 body.symmetries),
        "omega_rel": float(np.linalg.norm(res.params[9:12] - W) / np.linalg.norm(W)),
        "position_rel_range": float(np.linalg.norm(res.params[0:3] - X) / np.linalg.norm(X)),
        "velocity_rel": float(np.linalg.norm(res.params[6:9] - V) / np.linalg.norm(V)),
        "gravity_deg": float(np.degrees(np.arccos(np.clip(g @ ge / (g @ g), -1, 1)))),
        "mean_iou_footage": float(res.mean_iou),
    }
    e["mean_iou"] = float(np.mean(iou_truth)) if iou_truth is not None else e["mean_iou_footage"]
    ok = {k: (e[k] >= v if k == "mean_iou" else e[k] <= v) for k, v in CRITERIA.items()}
    e["pass"] = {k: bool(v) for k, v in ok.items()}
    e["success"] = bool(all(ok.values()))
    return e
