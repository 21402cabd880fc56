"""Products of a rigid-body fit for reports and logs: simulated silhouettes, overlays, 3D paths,
and the two file formats other stages build on.

* ``fit.yaml``: :func:`fit_to_dict` / :func:`fit_from_dict` (exact round trip through YAML);
* ``masks.npz``: ``masks`` (N, H, W) bool, ``times`` (N,) float seconds (:func:`masks_from_npz`
  validates a loaded file: ``masks_from_npz(np.load(path))``).

Pure functions returning arrays and dictionaries; writing them (PNG, Rerun, YAML) is the caller's
business.
"""

from __future__ import annotations

from collections.abc import Mapping

import cv2
import numpy as np

from vidsim.rigid.body import BoxBody, RigidBodyError
from vidsim.rigid.dynamics import G_EARTH, N_PARAM, PARAM_NAMES, gravity_vector, quat_to_rot, simulate
from vidsim.rigid.fit import Candidate, FitResult
from vidsim.rigid.silhouette import render_coverage
from vidsim.video.camera import PinholeCamera


def simulated_states(res: FitResult, body: BoxBody, times: np.ndarray) -> np.ndarray:
    """(T, 13) states of the fitted throw at ``times`` (seconds, >= ``res.t0``)."""
    return simulate(res.params, res.q0, body.inertia, np.asarray(times, float), res.t0, res.hmax,
                    sensitivities=False, g=res.gravity).states


def simulated_masks(res: FitResult, body: BoxBody, cam: PinholeCamera) -> np.ndarray:
    """(T, H, W) bool silhouettes of the fit at its fitted frames."""
    s = res.states
    return render_coverage(s[:, 0:3], s[:, 3:7], body.box_vertices(), cam) > 0.5


def overlay(frames: np.ndarray, sim: np.ndarray, obs: np.ndarray | None = None) -> np.ndarray:
    """Frames (T, H, W, 3) uint8 with the simulated silhouette's outline in green and the observed
    one's in magenta (seed Figure 2's superimposed silhouettes)."""
    out = np.array(frames, dtype=np.uint8, copy=True)
    for k in range(out.shape[0]):
        for m, color in ((obs, (255, 0, 255)), (sim, (0, 255, 0))):
            if m is None:
                continue
            cs, _ = cv2.findContours(np.asarray(m[k], np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
            cv2.drawContours(out[k], cs, -1, color, 1)
    return out


def corner_paths(states: np.ndarray, body: BoxBody) -> np.ndarray:
    """(T, 8B, 3) world paths of every box corner (the seed tracks a corner to show the match)."""
    V = body.box_vertices().reshape(-1, 3)
    return np.stack([V @ quat_to_rot(s[3:7]).T + s[0:3] for s in states])


# ----------------------------------------------------------------------------- fit.yaml / masks.npz
FIT_FORMAT = "vidsim.rigid.fit/1"
"""Value of ``format`` in a ``fit.yaml`` written from :func:`fit_to_dict`."""

MASKS_FORMAT_DOC = """masks.npz of the segment stage: ``masks`` (N, H, W) bool silhouettes of every
footage frame (True = object), ``times`` (N,) float64 frame times in seconds (the footage's)."""


def _candidate_to_dict(c: Candidate) -> dict:
    return {
        "start": int(c.start),
        "position": c.params[0:3].tolist(),
        "quaternion": c.q_base.tolist(),
        "velocity": c.params[6:9].tolist(),
        "omega_world": c.params[9:12].tolist(),
        "tilt": float(c.params[12]),
        "roll": float(c.params[13]),
        "params": c.params.tolist(),
        "cost": float(c.cost),
        "mean_iou": float(c.mean_iou),
        "iou": np.asarray(c.iou, float).tolist(),
        "history": [float(h) for h in c.history],
    }


def fit_to_dict(res: FitResult, body: BoxBody, cam: PinholeCamera | None = None) -> dict:
    """Plain (YAML-safe) dictionary of a fit: named parameters first, everything to rebuild it.

    Keys: ``format``; the named estimate at time ``t0`` (``position`` m, ``quaternion`` (w,x,y,z)
    body -> world, ``velocity`` m/s, ``omega_world`` rad/s, ``tilt``/``roll`` rad,
    ``gravity_direction`` unit (3,) in the calibration's world frame, ``gravity_magnitude`` m/s^2
    (known, not fitted), ``hmax`` the RK4 step bound, s); ``mean_iou``, ``iou`` (T,),
    ``ambiguous`` (true/false, or null with ``ambiguous_note`` when fewer than two candidates were
    refined and nothing was compared), ``distinct_alternatives``; ``params`` (14,) raw vector
    (:data:`PARAM_NAMES`);
    ``times`` (T,) s, ``frames`` (T,) footage indices, ``states`` (T, 13); ``history``;
    ``alternatives`` (list of candidates, best first), ``seconds``, ``n_starts``; ``object`` (the
    body's ``meta.yaml`` description, so a reader can rebuild it with ``BoxBody.from_meta``).
    With ``cam``: ``world_frame`` (what the frame of the estimate is, and the calibration's ``R``,
    ``t``: world -> camera) and ``gravity_direction_camera`` (``R`` times ``gravity_direction``):
    every vector above is in the calibration's world frame, which is the camera frame only when
    ``R = I, t = 0``.

    Args:
        res: the estimate.
        body: the body it was fitted with.
        cam: the camera it was fitted with (optional: labels the frame).

    Returns:
        dictionary; :func:`fit_from_dict` inverts it exactly (floats survive YAML by repr).
    """
    g = gravity_vector(float(res.params[12]), float(res.params[13]), 1.0)
    d = {
        "format": FIT_FORMAT,
        "t0": float(res.t0),
        "position": res.params[0:3].tolist(),
        "quaternion": np.asarray(res.q0, float).tolist(),
        "velocity": res.params[6:9].tolist(),
        "omega_world": res.params[9:12].tolist(),
        "tilt": float(res.params[12]),
        "roll": float(res.params[13]),
        "gravity_direction": g.tolist(),
        "gravity_magnitude": float(res.gravity),
        "mean_iou": float(res.mean_iou),
        "iou": np.asarray(res.iou, float).tolist(),
        "ambiguous": None if res.ambiguous is None else bool(res.ambiguous),
        "distinct_alternatives": [int(i) for i in res.distinct],
        "param_names": list(PARAM_NAMES),
        "params": np.asarray(res.params, float).tolist(),
        "times": np.asarray(res.times, float).tolist(),
        "frames": [int(i) for i in res.frames],
        "states": np.asarray(res.states, float).tolist(),
        "history": [float(h) for h in res.history],
        "seconds": float(res.seconds),
        "n_starts": int(res.n_starts),
        "hmax": float(res.hmax),
        "alternatives": [_candidate_to_dict(c) for c in res.alternatives],
        "object": body.to_meta(),
    }
    if cam is not None:
        d["world_frame"] = {
            "note": ("position, quaternion, velocity, omega_world, gravity_direction and states are in the world "
                     "frame of the calibration (R, t: world -> camera); " + (
                         "here R = I and t = 0, so it is the camera frame (x right, y down, z forward)"
                         if is_camera_frame(cam) else "here R != I or t != 0: it is NOT the camera frame")),
            "R": np.asarray(cam.R, float).tolist(), "t": np.asarray(cam.t, float).tolist()}
        d["gravity_direction_camera"] = (np.asarray(cam.R, float) @ g).tolist()
    if res.ambiguous is None:
        d["ambiguous_note"] = (f"not checked: {1 + len(res.alternatives)} candidate(s) refined, the two-solution "
                               "report compares at least two (rigid.fit.multistart=none or a last screen_keep of 1)")
    return d


def is_camera_frame(cam: PinholeCamera, atol: float = 1e-9) -> bool:
    """Whether the calibration's world frame is the camera frame (``R = I``, ``t = 0``)."""
    return bool(np.allclose(cam.R, np.eye(3), rtol=0, atol=atol) and np.allclose(cam.t, 0.0, rtol=0, atol=atol))


def _arr(d: dict, key: str, shape: tuple, where: str) -> np.ndarray:
    if key not in d:
        raise RigidBodyError(f"{where}: missing field '{key}'")
    try:
        a = np.asarray(d[key], float)
    except (TypeError, ValueError) as e:
        raise RigidBodyError(f"{where}: field '{key}' is not numeric ({e})") from e
    if a.ndim == 1 and len(shape) == 2 and a.size == 0:
        a = a.reshape(0, shape[1])
    if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape)):
        raise RigidBodyError(f"{where}: field '{key}' has shape {a.shape}, expected {shape}")
    if not np.all(np.isfinite(a)):
        raise RigidBodyError(f"{where}: field '{key}' has non-finite values")
    return a


def fit_from_dict(d: dict, where: str = "fit.yaml") -> FitResult:
    """Rebuild a :class:`FitResult` from :func:`fit_to_dict`'s dictionary (e.g. a loaded fit.yaml).

    Args:
        d: the dictionary.
        where: name used in error messages.

    Returns:
        the fit (the body is ``BoxBody.from_meta(d['object'])``).

    Raises:
        RigidBodyError: a field is missing or malformed (the message names it).
    """
    if not isinstance(d, dict):
        raise RigidBodyError(f"{where}: expected a mapping, got {type(d).__name__}")
    if d.get("format", FIT_FORMAT) != FIT_FORMAT:
        raise RigidBodyError(f"{where}: 'format' is {d.get('format')!r}, expected {FIT_FORMAT!r}")
    params = _arr(d, "params", (N_PARAM,), where)
    q0 = _arr(d, "quaternion", (4,), where)
    times = _arr(d, "times", (None,), where)
    T = len(times)
    states = _arr(d, "states", (T, 13), where)
    iou = _arr(d, "iou", (T,), where)
    frames = np.asarray(_arr(d, "frames", (T,), where), np.int64)
    alts = []
    for k, c in enumerate(d.get("alternatives", [])):
        w = f"{where}: alternatives[{k}]"
        if not isinstance(c, dict):
            raise RigidBodyError(f"{w}: expected a mapping")
        alts.append(Candidate(_arr(c, "params", (N_PARAM,), w), _arr(c, "quaternion", (4,), w),
                              float(c.get("cost", np.nan)), float(c.get("mean_iou", np.nan)),
                              _arr(c, "iou", (None,), w), [float(h) for h in c.get("history", [])],
                              int(c.get("start", -1))))
    for key in ("t0", "mean_iou"):
        if key not in d:
            raise RigidBodyError(f"{where}: missing field '{key}'")
    return FitResult(params, q0, float(d["t0"]), times, frames, states, iou, float(d["mean_iou"]),
                     [float(h) for h in d.get("history", [])], alts, _ambiguous(d, where),
                     float(d.get("seconds", 0.0)), int(d.get("n_starts", 0)),
                     [int(i) for i in d.get("distinct_alternatives", [])],
                     float(d.get("gravity_magnitude", G_EARTH)), float(d.get("hmax", 1.0 / 60.0)))


def _ambiguous(d: dict, where: str) -> bool | None:
    """``ambiguous`` of a fit.yaml: true/false, or null (not checked: fewer than two candidates)."""
    v = d.get("ambiguous", False)
    if v is None or isinstance(v, (bool, np.bool_)):
        return None if v is None else bool(v)
    raise RigidBodyError(f"{where}: field 'ambiguous' must be true, false or null (not checked), got {v!r}")


def check_masks(masks: np.ndarray, times: np.ndarray, where: str = "masks.npz") -> tuple[np.ndarray, np.ndarray]:
    """Validate the segment stage's arrays (see :data:`MASKS_FORMAT_DOC`).

    Args:
        masks: (N, H, W) silhouettes (any dtype; nonzero = object).
        times: (N,) frame times, seconds, strictly increasing.
        where: name used in error messages.

    Returns:
        (masks as bool (N, H, W), times as float64 (N,)).
    """
    m = np.asarray(masks)
    t = np.asarray(times, float)
    if m.ndim != 3:
        raise RigidBodyError(f"{where}: 'masks' must be (N, H, W), got shape {m.shape}")
    if t.shape != (m.shape[0],):
        raise RigidBodyError(f"{where}: 'times' must be ({m.shape[0]},) to match 'masks', got {t.shape}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise RigidBodyError(f"{where}: 'times' must be finite and strictly increasing")
    return m.astype(bool), t


def masks_from_npz(npz: Mapping[str, np.ndarray], where: str = "masks.npz") -> tuple[np.ndarray, np.ndarray]:
    """(masks, times) from a loaded masks.npz mapping (``np.load(path)``), validated."""
    for key in ("masks", "times"):
        if key not in npz:
            raise RigidBodyError(f"{where}: missing array '{key}' (has {sorted(npz.keys())})")
    return check_masks(npz["masks"], npz["times"], where)
