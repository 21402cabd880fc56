"""Pinhole camera with OpenCV lens distortion (the one camera model of the project).

Conventions (OpenCV): a world point ``X`` (metres) maps to camera coordinates
``x_c = R @ X + t``; the camera looks along +z, image x to the right, image y down.
Pixel coordinates are continuous, with (0, 0) the centre of the top-left pixel.
Distortion follows OpenCV's ``(k1, k2, p1, p2, k3)`` model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class CameraError(ValueError):
    """A camera description is not physical or not consistent."""


@dataclass
class PinholeCamera:
    """A calibrated pinhole camera.

    Attributes:
        K: (3, 3) intrinsic matrix in pixels.
        R: (3, 3) rotation world -> camera.
        t: (3,) translation world -> camera, metres.
        width: image width in pixels.
        height: image height in pixels.
        dist: (5,) OpenCV distortion ``k1, k2, p1, p2, k3`` (zeros = ideal lens).
    """

    K: np.ndarray
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    t: np.ndarray = field(default_factory=lambda: np.zeros(3))
    width: int = 640
    height: int = 480
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))

    def __post_init__(self) -> None:
        self.K = np.asarray(self.K, dtype=float).reshape(3, 3)
        self.R = np.asarray(self.R, dtype=float).reshape(3, 3)
        self.t = np.asarray(self.t, dtype=float).reshape(3)
        self.dist = _dist5(self.dist, "camera")
        self.width, self.height = int(self.width), int(self.height)
        self.validate()

    # ------------------------------------------------------------------ checks
    def validate(self, where: str = "camera") -> None:
        """Raise :class:`CameraError` naming the field when the camera is not usable."""
        for name in ("K", "R", "t", "dist"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise CameraError(f"{where}: field '{name}' contains NaN or inf")
        if self.width <= 0 or self.height <= 0:
            raise CameraError(f"{where}: image size must be positive, got {self.width}x{self.height}")
        fx, fy = self.K[0, 0], self.K[1, 1]
        if fx <= 0 or fy <= 0 or abs(np.linalg.det(self.K)) < 1e-9:
            raise CameraError(f"{where}: field 'K' is singular or has non-positive focal length (fx={fx}, fy={fy})")
        if abs(np.linalg.det(self.R) - 1.0) > 1e-4 or not np.allclose(self.R @ self.R.T, np.eye(3), atol=1e-4):
            raise CameraError(f"{where}: field 'R' is not a rotation matrix")

    # ------------------------------------------------------------- properties
    @property
    def P(self) -> np.ndarray:
        """(3, 4) projection matrix ``K [R | t]`` (ignores distortion)."""
        return self.K @ np.hstack([self.R, self.t[:, None]])

    @property
    def center(self) -> np.ndarray:
        """(3,) camera centre in world coordinates, metres."""
        return -self.R.T @ self.t

    def scaled(self, factor: float) -> "PinholeCamera":
        """The same camera with the image resampled by ``factor`` (for image pyramids).

        The new image is ``round(W factor)`` x ``round(H factor)`` pixels, and each axis of K is scaled by
        the ratio of the sizes (what ``cv2.resize`` to that size does), not by ``factor`` itself: for an
        odd size the two differ (321 px at 0.5 is 160 px, a scale of 0.4984), half a pixel at the edge."""
        w, h = round(self.width * factor), round(self.height * factor)
        sx, sy = w / self.width, h / self.height
        K = np.diag([sx, sy, 1.0]) @ self.K
        # pixel-centre convention: x' = s*(x + 0.5) - 0.5
        K[0, 2] = sx * (self.K[0, 2] + 0.5) - 0.5
        K[1, 2] = sy * (self.K[1, 2] + 0.5) - 0.5
        return PinholeCamera(K, self.R, self.t, w, h, self.dist)

    # ------------------------------------------------------------- projection
    def to_camera(self, X: np.ndarray) -> np.ndarray:
        """World points (N, 3) -> camera coordinates (N, 3)."""
        return np.asarray(X, dtype=float) @ self.R.T + self.t

    def project(self, X: np.ndarray, distort: bool = True) -> np.ndarray:
        """Project world points (N, 3) to pixels (N, 2); points behind the camera give NaN."""
        Xc = self.to_camera(X)
        z = Xc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = Xc[:, 0] / z
            y = Xc[:, 1] / z
        if distort and np.any(self.dist):
            x, y = distort_normalized(x, y, self.dist)
        u = self.K[0, 0] * x + self.K[0, 1] * y + self.K[0, 2]
        v = self.K[1, 1] * y + self.K[1, 2]
        uv = np.stack([u, v], axis=1)
        uv[z <= 1e-9] = np.nan
        return uv

    def ray_directions(self) -> np.ndarray:
        """(H, W, 3) unit ray directions in world coordinates through each pixel centre (no distortion)."""
        u, v = np.meshgrid(np.arange(self.width, dtype=float), np.arange(self.height, dtype=float))
        Kinv = np.linalg.inv(self.K)
        pix = np.stack([u, v, np.ones_like(u)], axis=-1)
        d_cam = pix @ Kinv.T
        d = d_cam @ self.R  # R^T d_cam, row-vector form
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    # ------------------------------------------------------------------- I/O
    def to_dict(self) -> dict:
        """Plain-python dictionary (YAML friendly)."""
        return {
            "width": self.width,
            "height": self.height,
            "K": self.K.tolist(),
            "dist": self.dist.tolist(),
            "R": self.R.tolist(),
            "t": self.t.tolist(),
        }

    @classmethod
    def from_dict(cls, d: dict, where: str = "camera") -> "PinholeCamera":
        """Build from :meth:`to_dict` output; errors name ``where`` and the missing field."""
        missing = [k for k in ("width", "height", "K") if k not in d]
        if missing:
            raise CameraError(f"{where}: missing field(s) {missing}")
        try:
            K = np.asarray(d["K"], dtype=float)
        except (TypeError, ValueError) as e:
            raise CameraError(f"{where}: field 'K' is not a numeric 3x3 matrix") from e
        if K.shape != (3, 3):
            raise CameraError(f"{where}: field 'K' must be 3x3, got shape {K.shape}")
        cam = cls.__new__(cls)
        cam.K = K
        for name, default in (("R", np.eye(3)), ("t", np.zeros(3))):
            try:
                setattr(cam, name, np.asarray(d.get(name, default), dtype=float))
            except (TypeError, ValueError):
                raise CameraError(f"{where}: field '{name}' is not numeric (got {d.get(name)!r})") from None
        for name in ("width", "height"):
            v = d[name]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or float(v) != int(v):
                raise CameraError(f"{where}: field '{name}' must be a whole number of pixels, got {v!r}")
        cam.width, cam.height = int(d["width"]), int(d["height"])
        cam.dist = _dist5(d.get("dist", np.zeros(5)), where)
        if cam.R.shape != (3, 3):
            raise CameraError(f"{where}: field 'R' must be 3x3, got shape {cam.R.shape}")
        if cam.t.shape != (3,):
            raise CameraError(f"{where}: field 't' must have 3 entries, got shape {cam.t.shape}")
        cam.validate(where)
        return cam


def _dist5(dist, where: str) -> np.ndarray:
    """The five OpenCV coefficients ``k1, k2, p1, p2, k3`` (fewer are padded with zeros); a longer
    vector (the rational or thin-prism models) is refused rather than cut to a different lens."""
    try:
        dd = np.asarray(dist, dtype=float).ravel()
    except (TypeError, ValueError):
        raise CameraError(f"{where}: field 'dist' is not numeric (got {dist!r})") from None
    if dd.size > 5 and np.any(dd[5:] != 0):
        raise CameraError(f"{where}: field 'dist' has {dd.size} coefficients with non-zero ones beyond k3; only "
                          "OpenCV's five-coefficient model (k1, k2, p1, p2, k3) is supported")
    d = np.zeros(5)
    d[: min(5, dd.size)] = dd[:5]
    return d


def distort_normalized(x: np.ndarray, y: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Apply OpenCV's radial-tangential distortion to normalised coordinates."""
    k1, k2, p1, p2, k3 = dist[:5]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return xd, yd


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = np.array([0.0, 0.0, 1.0])) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and translation (world -> camera, OpenCV axes) of a camera at ``eye`` looking at ``target``.

    ``up`` is the world direction that should appear up (negative image y) in the image.
    """
    eye = np.asarray(eye, float)
    z = np.asarray(target, float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, float))  # image x = right when 'up' is up
    if np.linalg.norm(x) < 1e-9:
        raise CameraError("look_at: viewing direction is parallel to 'up'")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    return R, -R @ eye


def intrinsics(fx: float, fy: float | None, cx: float, cy: float) -> np.ndarray:
    """(3, 3) intrinsic matrix from focal lengths and principal point (pixels)."""
    fy = fx if fy is None else fy
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
