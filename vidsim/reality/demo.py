"""The foundation's demo reality: a box on a ballistic arc with a constant spin.

Kinematic (a constant angular velocity, exact for a sphere-like inertia): it exists to exercise
reality -> footage -> report end to end; the rigid-body reality uses MuJoCo.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation


@dataclass
class DemoMotion:
    """Per-frame pose of the box. ``R``: (T,3,3) body->world, ``X``: (T,3) metres, ``visible``: (T,) bool."""

    times: np.ndarray
    R: np.ndarray
    X: np.ndarray
    visible: np.ndarray


def box_mesh(size: tuple[float, float, float] = (0.3, 0.1, 0.1)) -> tuple[np.ndarray, np.ndarray]:
    """Closed box centred at the origin: vertices (8,3) metres, faces (12,3), outward winding."""
    sx, sy, sz = (np.asarray(size) / 2).tolist()
    V = np.array([[x, y, z] for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)], float)
    F = np.array(
        [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], int)
    return V, F


def demo_motion(n_frames: int, fps: float, lead_in_s: float, rng: np.random.Generator,
                g: np.ndarray = np.array([0.0, 0.0, -9.81])) -> tuple[DemoMotion, dict]:
    """Sample a throw (seeded) and return the per-frame poses and the truth dictionary."""
    times = np.arange(n_frames) / fps
    X0 = np.array([-0.8, 0.0, 0.7]) + rng.normal(0, 0.03, 3)
    V0 = np.array([1.6, 0.0, 3.2]) + rng.normal(0, 0.1, 3)
    w = rng.normal(0, 4.0, 3)
    q0 = Rotation.random(random_state=int(rng.integers(1 << 31)))
    ta = np.clip(times - lead_in_s, 0, None)
    X = X0 + V0 * ta[:, None] + 0.5 * g * ta[:, None] ** 2
    R = np.stack([(Rotation.from_rotvec(w * t) * q0).as_matrix() for t in ta])
    visible = times >= lead_in_s
    truth = {"X0": X0, "V0": V0, "omega": w, "quat0_xyzw": q0.as_quat(), "gravity": g, "lead_in_s": lead_in_s}
    return DemoMotion(times, R, X, visible), truth
