"""Products of a rigid-body fit for reports and logs: simulated silhouettes, overlays, 3D paths.

Pure functions returning arrays; writing them (PNG, Rerun, YAML) is the caller's business.
"""

from __future__ import annotations

import cv2
import numpy as np

from vidsim.rigid.body import BoxBody
from vidsim.rigid.dynamics import quat_to_rot, simulate
from vidsim.rigid.fit import FitResult
from vidsim.rigid.silhouette import render_coverage
from vidsim.video.camera import PinholeCamera


def simulated_states(res: FitResult, body: BoxBody, times: np.ndarray) -> np.ndarray:
    """(T, 13) states of the fitted throw at ``times`` (seconds, >= ``res.t0``)."""
    return simulate(res.params, res.q0, body.inertia, np.asarray(times, float), res.t0, sensitivities=False).states


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
