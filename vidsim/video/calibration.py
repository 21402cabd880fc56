"""Camera and projector calibration from images of a planar chessboard target.

The camera is calibrated with Zhang's method (``cv2.calibrateCamera``) from inner corners of a
printed chessboard, found by ``cv2.findChessboardCorners`` and refined to sub-pixel accuracy by
``cv2.cornerSubPix``. The world frame of a scene is the frame of the target at a chosen reference
view (like the marker grid the seed document calibrates camera and projector with).

A projector is calibrated as an inverse camera. At each pose of the white target the camera takes
two images with the same exposure and ambient light: one with the projector dark (the printed
chessboard gives the target's pose) and one with the projector casting a known chessboard pattern
onto the blank part of the target. The difference of the two images holds only the projected
light; its corners are found, their camera rays are intersected with the target plane, and the
resulting 3-D points are matched with the known projector pixels of the pattern corners to
estimate the projector's intrinsics and its pose relative to the camera.

Why a chessboard and not a grid of dots: chessboard inner corners are saddle points whose image
position is unbiased under perspective and under symmetric blur, while the centroid of a projected
dot (an ellipse) is biased under perspective. The same detector also serves real photographs.

Board frame (OpenCV convention): origin at the first inner corner, x along the ``pattern_size[0]``
corners of a row, y along the rows, z into the board (away from a camera that sees its printed
face); units are metres. The square diagonally before corner 0 (centred at ``(-s/2, -s/2)``) is
black; detections are put in this canonical order so that the frame is unambiguous.

Capture protocol (real or synthetic): ``target_images[i]`` shows the target with the projector
dark; ``projector_images[i]`` (optional, per view) shows the same pose with the same exposure
and the projector casting :class:`ProjectorPattern` onto the blank part of the board.

Synthetic footage of the target (:func:`render_target_views`, :func:`film_calibration_target`)
is made by ray-plane intersection for each camera pixel through the distorted lens; the board
texture and the projected pattern are box-filtered analytically over each sample's footprint
(no aliasing), then blur and sensor noise are added, so the project can film a calibration
target in its synthetic realities.

Pixel convention everywhere: (0, 0) is the centre of the top-left pixel.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Sequence

import cv2
import numpy as np

from vidsim.video.camera import PinholeCamera, distort_normalized

try:  # the project-wide base of input errors, when present
    from vidsim.errors import VidsimError as _BaseError
except ImportError:  # pragma: no cover - older trees without vidsim/errors.py
    _BaseError = ValueError


class CalibrationError(_BaseError):
    """Calibration cannot proceed: no target found, too few views, inconsistent images."""


#: Sub-pixel refinement criteria of OpenCV's calibration sample (30 iterations or 0.1 px):
#: these reproduce OpenCV's reference calibration of its left01..left14 images.
SUBPIX_CRITERIA: tuple[int, int, float] = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.1)
_FIND_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK


# --------------------------------------------------------------------------------------------
# Target description
# --------------------------------------------------------------------------------------------

def _five_coefficient_model(flags: int, where: str) -> None:
    """The project's cameras carry OpenCV's five-coefficient lens (k1, k2, p1, p2, k3); flags that
    ask OpenCV for a longer model would return coefficients this code would have to drop."""
    longer = [n for n in ("CALIB_RATIONAL_MODEL", "CALIB_THIN_PRISM_MODEL", "CALIB_TILTED_MODEL")
              if flags & getattr(cv2, n, 0)]
    if longer:
        raise CalibrationError(f"{where}: flags {longer} ask for more than five distortion coefficients; only "
                               "k1, k2, p1, p2, k3 are supported")

def _box_step(d: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Unit step box-filtered over width ``w``: a linear ramp in the signed distance ``d``."""
    return np.clip(0.5 + d / w, 0.0, 1.0)


def _box_parity(c: np.ndarray, s: float, w: np.ndarray) -> np.ndarray:
    """``sign(sin(pi c / s))`` box-filtered over width ``w`` (same units as ``c`` and ``s``)."""
    u = c / s
    fu = u - np.floor(u)
    sign = np.where(np.floor(u) % 2 == 0, 1.0, -1.0)
    return np.clip(2.0 * sign * np.minimum(fu, 1.0 - fu) * s / w, -1.0, 1.0)


@dataclass(frozen=True)
class ChessboardTarget:
    """A white planar board with a printed chessboard and a blank area for projected patterns.

    Attributes:
        pattern_size: inner corners (per row, rows), e.g. ``(9, 6)`` for a board of 10x7 squares.
        square_size: side of a printed square, metres.
        board_extent: ``(x_min, x_max, y_min, y_max)`` of the white board in the board frame,
            metres; it must contain the printed squares. Outside it the scene is ``background``.
        white: albedo of the board and of the white squares (0..1).
        black: albedo of the printed black squares (0..1).
        background: albedo of what lies outside the board (0..1).
    """

    pattern_size: tuple[int, int] = (9, 6)
    square_size: float = 0.04
    board_extent: tuple[float, float, float, float] = (-0.08, 0.90, -0.10, 0.34)
    white: float = 0.9
    black: float = 0.06
    background: float = 0.2

    def __post_init__(self) -> None:
        nx, ny = self.pattern_size
        if nx < 2 or ny < 2:
            raise CalibrationError(f"target: pattern_size must be at least (2, 2) inner corners, got {self.pattern_size}")
        if (nx + ny) % 2 == 0:
            raise CalibrationError(
                f"target: pattern_size {self.pattern_size} gives a board that looks the same turned by 180 degrees; "
                "use one even and one odd number of inner corners (e.g. (9, 6)) so the board frame is unambiguous"
            )
        if not self.square_size > 0:
            raise CalibrationError(f"target: square_size must be > 0 metres, got {self.square_size}")
        x0, x1, y0, y1 = self.board_extent
        s = self.square_size
        if not (x0 <= -s and y0 <= -s and x1 >= nx * s and y1 >= ny * s):
            raise CalibrationError(
                f"target: board_extent {self.board_extent} must contain the printed squares "
                f"[{-s}, {nx * s}] x [{-s}, {ny * s}] m"
            )

    def object_points(self) -> np.ndarray:
        """(N, 3) inner corners in the board frame, metres, row-major (x fastest), z = 0."""
        return chessboard_object_points(self.pattern_size, self.square_size)

    def albedo(self, x: np.ndarray, y: np.ndarray, footprint: np.ndarray | float | None = None) -> np.ndarray:
        """Albedo (0..1) at board-frame points ``x, y`` (any equal shapes, metres).

        Args:
            x, y: board-frame coordinates, metres.
            footprint: width (metres) of the box filter each sample stands for (scalar or the
                shape of ``x``); edges become linear ramps of that width, which is the exact box
                average across a straight edge. ``None``: hard edges (point samples).
        """
        nx, ny = self.pattern_size
        s = self.square_size
        if footprint is None:
            a = np.floor(x / s) + 1  # square index along x, 0..nx on the print
            b = np.floor(y / s) + 1
            on_print = (a >= 0) & (a <= nx) & (b >= 0) & (b <= ny)
            is_black = on_print & (((a + b) % 2) == 0)
            x0, x1, y0, y1 = self.board_extent
            on_board = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
            out = np.where(is_black, self.black, self.white)
            return np.where(on_board, out, self.background)
        w = np.maximum(np.asarray(footprint, float), 1e-12)

        def step(d: np.ndarray) -> np.ndarray:
            return _box_step(d, w)

        # square (a, b) is black when a + b is even <=> sign(sin(pi x/s)) * sign(sin(pi y/s)) = +1
        black = 0.5 * (1.0 + _box_parity(x, s, w) * _box_parity(y, s, w))
        on_print = step(x + s) * step(nx * s - x) * step(y + s) * step(ny * s - y)
        printed = self.white + (self.black - self.white) * black * on_print
        x0, x1, y0, y1 = self.board_extent
        on_board = step(x - x0) * step(x1 - x) * step(y - y0) * step(y1 - y)
        return self.background + (printed - self.background) * on_board


def chessboard_object_points(pattern_size: tuple[int, int], square_size: float) -> np.ndarray:
    """(N, 3) inner-corner coordinates in the board frame, metres, row-major, z = 0.

    Args:
        pattern_size: inner corners (per row, rows).
        square_size: square side, metres.
    """
    nx, ny = int(pattern_size[0]), int(pattern_size[1])
    obj = np.zeros((nx * ny, 3))
    obj[:, :2] = np.mgrid[0:nx, 0:ny].T.reshape(-1, 2) * float(square_size)
    return obj


@dataclass(frozen=True)
class ProjectorPattern:
    """A chessboard image cast by a projector, framed by one square of white quiet zone.

    Attributes:
        width: projector image width, pixels.
        height: projector image height, pixels.
        pattern_size: inner corners (per row, rows).
        square_px: square side in projector pixels (integer: edges fall on pixel boundaries).
        origin: ``(u, v)`` of the first (top-left) pixel of the checker squares; the quiet zone
            starts ``square_px`` before it. Default: the checker is centred in the image.
    """

    width: int = 800
    height: int = 600
    pattern_size: tuple[int, int] = (7, 4)
    square_px: int = 28
    origin: tuple[int, int] | None = None

    def _origin(self) -> tuple[int, int]:
        if self.origin is not None:
            return int(self.origin[0]), int(self.origin[1])
        nx, ny = self.pattern_size
        return (self.width - (nx + 1) * self.square_px) // 2, (self.height - (ny + 1) * self.square_px) // 2

    def __post_init__(self) -> None:
        nx, ny = self.pattern_size
        if nx < 2 or ny < 2:
            raise CalibrationError(f"projector pattern: pattern_size must be >= (2, 2), got {self.pattern_size}")
        if (nx + ny) % 2 == 0:
            raise CalibrationError(
                f"projector pattern: pattern_size {self.pattern_size} looks the same turned by 180 degrees; "
                "use one even and one odd number of inner corners (e.g. (7, 4))"
            )
        if self.square_px < 4:
            raise CalibrationError(f"projector pattern: square_px must be >= 4 pixels, got {self.square_px}")
        u0, v0 = self._origin()
        s = self.square_px
        if u0 - s < 0 or v0 - s < 0 or u0 + (nx + 2) * s > self.width or v0 + (ny + 2) * s > self.height:
            raise CalibrationError(
                f"projector pattern: checker with quiet zone does not fit a {self.width}x{self.height} image "
                f"(origin {(u0, v0)}, square_px {s}, pattern_size {self.pattern_size})"
            )

    def corners(self) -> np.ndarray:
        """(N, 2) projector pixel coordinates of the inner corners, row-major (canonical order)."""
        nx, ny = self.pattern_size
        u0, v0 = self._origin()
        ij = np.mgrid[0:nx, 0:ny].T.reshape(-1, 2).astype(float)
        return np.stack([u0 - 0.5 + (ij[:, 0] + 1) * self.square_px, v0 - 0.5 + (ij[:, 1] + 1) * self.square_px], axis=1)

    def radiance(self, u: np.ndarray, v: np.ndarray, footprint: np.ndarray | float) -> np.ndarray:
        """Pattern value (0..1) at continuous projector pixel coordinates, box-filtered.

        Equals :meth:`image` sampled at pixel centres when ``footprint`` is small; edges lie on
        pixel boundaries, so the analytic form is the projector's raster exactly.

        Args:
            u, v: projector pixel coordinates (any equal shapes).
            footprint: filter width in projector pixels (scalar or the shape of ``u``).
        """
        nx, ny = self.pattern_size
        u0, v0 = self._origin()
        s = float(self.square_px)
        w = np.maximum(np.asarray(footprint, float), 1e-12)
        xs, ys = u - (u0 - 0.5), v - (v0 - 0.5)
        black = 0.5 * (1.0 + _box_parity(xs, s, w) * _box_parity(ys, s, w))
        in_checker = _box_step(xs, w) * _box_step((nx + 1) * s - xs, w) * _box_step(ys, w) * _box_step((ny + 1) * s - ys, w)
        in_frame = _box_step(xs + s, w) * _box_step((nx + 2) * s - xs, w) * _box_step(ys + s, w) * _box_step((ny + 2) * s - ys, w)
        return in_frame * (1.0 - black * in_checker)

    def image(self) -> np.ndarray:
        """(height, width) float image in [0, 1]: checker (square (0, 0) black), white frame, black elsewhere."""
        nx, ny = self.pattern_size
        u0, v0 = self._origin()
        s = self.square_px
        v, u = np.mgrid[0 : self.height, 0 : self.width]
        a = np.floor((u - u0) / s).astype(int)
        b = np.floor((v - v0) / s).astype(int)
        in_frame = (a >= -1) & (a <= nx + 1) & (b >= -1) & (b <= ny + 1)
        in_checker = (a >= 0) & (a <= nx) & (b >= 0) & (b <= ny)
        img = np.zeros((self.height, self.width))
        img[in_frame] = 1.0
        img[in_checker & (((a + b) % 2) == 0)] = 0.0
        return img


# --------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------
@dataclass
class CalibrationResult:
    """Outcome of a camera calibration.

    Attributes:
        K: (3, 3) intrinsic matrix, pixels.
        dist: (5,) OpenCV distortion ``k1, k2, p1, p2, k3``.
        rms: overall RMS reprojection error, pixels (``cv2.calibrateCamera``'s value).
        image_size: ``(width, height)`` in pixels.
        rvecs: (V, 3) Rodrigues rotations board -> camera of the used views.
        tvecs: (V, 3) translations board -> camera of the used views, metres.
        per_view_rms: (V,) RMS reprojection error of each used view, pixels.
        used: names of the V used images, in the order of ``rvecs``.
        rejected: image name -> reason it was not used.
        object_points: (N, 3) board-frame corners, metres.
        image_points: (V, N, 2) detected corners of the used views, pixels.
        flags: the ``cv2.CALIB_*`` flags used.
        pattern_size: inner corners (per row, rows) of the board.
        square_size: square side of the board, metres.
    """

    K: np.ndarray
    dist: np.ndarray
    rms: float
    image_size: tuple[int, int]
    rvecs: np.ndarray
    tvecs: np.ndarray
    per_view_rms: np.ndarray
    used: list[str]
    rejected: dict[str, str]
    object_points: np.ndarray
    image_points: np.ndarray
    flags: int = 0
    pattern_size: tuple[int, int] = (9, 6)
    square_size: float = 0.025

    @property
    def n_views(self) -> int:
        """Number of views used in the calibration."""
        return len(self.used)

    def view_index(self, view: int | str) -> int:
        """Index into ``used`` of a view given by index or by image name."""
        if isinstance(view, str):
            if view not in self.used:
                why = self.rejected.get(view)
                extra = f" (rejected: {why})" if why else ""
                raise CalibrationError(f"view '{view}' is not among the used views {self.used}{extra}")
            return self.used.index(view)
        i = int(view)
        if not -self.n_views <= i < self.n_views:
            raise CalibrationError(f"view index {i} out of range for {self.n_views} used views")
        return i % self.n_views

    def pose(self, view: int | str) -> tuple[np.ndarray, np.ndarray]:
        """``(R, t)``: board -> camera rotation (3, 3) and translation (3,) metres of a view."""
        i = self.view_index(view)
        R, _ = cv2.Rodrigues(self.rvecs[i].reshape(3, 1))
        return R, self.tvecs[i].copy()

    def to_dict(self) -> dict:
        """Plain-python summary (YAML friendly)."""
        return {
            "K": self.K.tolist(),
            "dist": self.dist.tolist(),
            "rms_px": float(self.rms),
            "image_size": list(self.image_size),
            "used": list(self.used),
            "rejected": dict(self.rejected),
            "per_view_rms_px": [float(e) for e in self.per_view_rms],
            "rvecs": self.rvecs.tolist(),
            "tvecs": self.tvecs.tolist(),
        }


@dataclass
class ProjectorCalibration:
    """Outcome of a projector calibration (the projector as an inverse camera).

    Attributes:
        K: (3, 3) projector intrinsics, projector pixels.
        dist: (5,) projector lens distortion (OpenCV model).
        R: (3, 3) rotation camera frame -> projector frame.
        t: (3,) translation camera frame -> projector frame, metres.
        image_size: projector ``(width, height)``, pixels.
        rms: RMS reprojection error of all 3-D points into the projector with the final pose,
            projector pixels.
        per_view_rms: (V,) the same per used view.
        used: names of the views used.
        rejected: view name -> reason.
        points_camera: (M, 3) triangulated pattern corners in the camera frame, metres.
        points_projector: (M, 2) their projector pixels.
    """

    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    t: np.ndarray
    image_size: tuple[int, int]
    rms: float
    per_view_rms: np.ndarray
    used: list[str]
    rejected: dict[str, str]
    points_camera: np.ndarray = field(repr=False)
    points_projector: np.ndarray = field(repr=False)


# --------------------------------------------------------------------------------------------
# Detection
# --------------------------------------------------------------------------------------------
def spread_patterns(base: ProjectorPattern, n: int, extent: float = 1.0) -> list[ProjectorPattern]:
    """``n`` copies of ``base`` whose checkers sit at positions spread over the projector image.

    A checker always cast at the image's centre covers a few percent of the projector's image,
    so its focal lengths and principal point are poorly determined even when the reprojection
    error is small. The copies visit a 3 x 3 grid of origins from one corner of the image (quiet
    zone included) to the other, centre first, then the corners, then the edge midpoints, and
    round again when ``n > 9``; ``extent`` (0-1] shrinks the grid about the image centre (1: the
    checker reaches the image's edges). The positions are an input the estimator knows (what was
    cast), like the pattern itself.
    """
    if int(n) < 1:
        raise CalibrationError(f"spread_patterns: n must be >= 1, got {n}")
    if not (0.0 < float(extent) <= 1.0):
        raise CalibrationError(f"spread_patterns: extent must be in (0, 1], got {extent}")
    nx, ny = base.pattern_size
    s = base.square_px
    u_hi, v_hi = base.width - (nx + 2) * s, base.height - (ny + 2) * s  # quiet zone inside the image
    uc, vc = (s + u_hi) / 2, (s + v_hi) / 2
    us = [int(round(uc + f * extent * (u_hi - s) / 2)) for f in (-1, 0, 1)]
    vs = [int(round(vc + f * extent * (v_hi - s) / 2)) for f in (-1, 0, 1)]
    order = [(1, 1), (0, 0), (2, 2), (2, 0), (0, 2), (1, 0), (1, 2), (0, 1), (2, 1)]
    return [replace(base, origin=(us[i], vs[j])) for i, j in (order[k % len(order)] for k in range(int(n)))]


def _patterns_per_view(pattern: ProjectorPattern | Sequence[ProjectorPattern | None] | None, n: int, what: str) -> list:
    """One pattern (or ``None``) per view: a single pattern is cast in every view."""
    if pattern is None or isinstance(pattern, ProjectorPattern):
        return [pattern] * n
    pats = list(pattern)
    if len(pats) != n:
        raise CalibrationError(f"{what}: {len(pats)} projector patterns for {n} views (one per view, or a single pattern, needed)")
    for i, p in enumerate(pats):
        if p is not None and not isinstance(p, ProjectorPattern):
            raise CalibrationError(f"{what}: pattern of view {i} is a {type(p).__name__}, expected a ProjectorPattern")
    return pats


def _as_gray_u8(img: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(img)
    if a.ndim == 3 and a.shape[2] in (3, 4):
        bgr = np.ascontiguousarray(a[..., :3])
        a = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY) if a.dtype == np.uint8 else bgr.mean(axis=2)
    if a.ndim != 2:
        raise CalibrationError(f"image '{name}': expected a (H, W) grayscale or (H, W, 3) colour image, got shape {a.shape}")
    if a.dtype == np.uint8:
        return a
    if not np.issubdtype(a.dtype, np.number):
        raise CalibrationError(f"image '{name}': expected numeric pixels, got dtype {a.dtype}")
    a = a.astype(float)
    if not np.all(np.isfinite(a)):
        raise CalibrationError(f"image '{name}': contains NaN or inf")
    top = a.max(initial=0.0)
    if top > 255.0:  # a 12- or 16-bit image: clipping it to 255 would leave a white frame and "no chessboard"
        raise CalibrationError(f"image '{name}': pixel values up to {top:g}; expected uint8, or numbers in "
                               "[0, 1] or [0, 255] (scale a 12/16-bit image to 8 bits first)")
    scale = 255.0 if top <= 1.0 else 1.0
    return np.clip(np.rint(a * scale), 0, 255).astype(np.uint8)


def _check_images(images: Sequence[np.ndarray], names: Sequence[str] | None, what: str) -> tuple[list[np.ndarray], list[str], tuple[int, int]]:
    if images is None or len(images) == 0:
        raise CalibrationError(f"{what}: no images given")
    if names is None:
        names = [f"{what}[{i}]" for i in range(len(images))]
    names = [str(n) for n in names]
    if len(names) != len(images):
        raise CalibrationError(f"{what}: {len(images)} images but {len(names)} image_names")
    grays = [_as_gray_u8(im, n) for im, n in zip(images, names)]
    sizes = {(g.shape[1], g.shape[0]) for g in grays}
    if len(sizes) > 1:
        ref = (grays[0].shape[1], grays[0].shape[0])
        odd = [f"{n} ({g.shape[1]}x{g.shape[0]})" for n, g in zip(names, grays) if (g.shape[1], g.shape[0]) != ref]
        raise CalibrationError(f"{what}: images differ in size; {names[0]} is {ref[0]}x{ref[1]} but {', '.join(odd)}")
    w, h = sizes.pop()
    return grays, names, (w, h)


def _canonical_order(gray: np.ndarray, corners: np.ndarray, pattern_size: tuple[int, int]) -> np.ndarray:
    """Reorder detected corners so that rows run along +x, the board is seen from its front,
    and the square diagonally before corner 0 is the dark one."""
    nx, ny = pattern_size
    c = corners.reshape(ny, nx, 2)
    # Seen from the printed side, board x and y (image y down) give a positive orientation.
    ex = c[0, -1] - c[0, 0]
    ey = c[-1, 0] - c[0, 0]
    if ex[0] * ey[1] - ex[1] * ey[0] < 0:
        c = c[:, ::-1]
    # Colour of the corner square: compare the square before corner 0 with its neighbour along x.
    src = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    H, _ = cv2.findHomography(src, np.array([c[0, 0], c[0, 1], c[1, 0], c[1, 1]]), 0)
    if H is not None:
        probes = np.array([[-0.5, -0.5], [0.5, -0.5]])
        p = cv2.perspectiveTransform(probes[None], H)[0]
        vals = []
        h, w = gray.shape
        for x, y in p:
            xi, yi = int(round(x)), int(round(y))
            if not (1 <= xi < w - 1 and 1 <= yi < h - 1):
                vals = []
                break
            vals.append(float(gray[yi - 1 : yi + 2, xi - 1 : xi + 2].mean()))
        if len(vals) == 2 and vals[0] > vals[1]:
            c = c[::-1, ::-1]
    return c.reshape(-1, 2)


def detect_chessboard(
    image: np.ndarray,
    pattern_size: tuple[int, int] = (9, 6),
    subpix_window: int | None = None,
    criteria: tuple[int, int, float] = SUBPIX_CRITERIA,
    thorough: bool = False,
) -> np.ndarray | None:
    """Find the inner corners of a chessboard with sub-pixel accuracy.

    Args:
        image: (H, W) grayscale or (H, W, 3) BGR image (uint8, or float in [0, 1]).
        pattern_size: inner corners (per row, rows).
        subpix_window: half-size of the ``cornerSubPix`` search window, pixels; ``None`` picks
            0.6 x the smallest corner spacing, at most 11 (OpenCV's sample value, reached for
            squares of 19 px and more), so that small squares keep neighbours out of the window.
        criteria: ``cornerSubPix`` termination criteria.
        thorough: when OpenCV's fast pre-check rejects the image, search again without it (the
            projector calibration's difference images: the pre-check turned down a clean, sharp
            projected checker near the image's corner in 8 of 10 sessions; review of 5 Dec 2026).

    Returns:
        (N, 2) corners in pixels in canonical order (see module docstring), or ``None`` when
        the board is not found. The order is unambiguous only for boards with one even and one
        odd number of inner corners (a board with both even or both odd looks the same turned
        by 180 degrees), and when the squares next to corner 0 are inside the image.
    """
    gray = _as_gray_u8(image, "image")
    ok, corners = cv2.findChessboardCorners(gray, tuple(int(p) for p in pattern_size), flags=_FIND_FLAGS)
    if (not ok or corners is None) and thorough:
        ok, corners = cv2.findChessboardCorners(gray, tuple(int(p) for p in pattern_size),
                                                flags=_FIND_FLAGS & ~cv2.CALIB_CB_FAST_CHECK)
    if not ok or corners is None:
        return None
    corners = corners.reshape(-1, 1, 2).astype(np.float32)
    if subpix_window is None:
        c = corners.reshape(pattern_size[1], pattern_size[0], 2)
        dx = np.linalg.norm(np.diff(c, axis=1), axis=2).min()
        dy = np.linalg.norm(np.diff(c, axis=0), axis=2).min()
        win = int(np.clip(0.6 * min(dx, dy), 2, 11))
    else:
        win = int(subpix_window)
    corners = cv2.cornerSubPix(gray, corners, (win, win), (-1, -1), criteria)
    return _canonical_order(gray, corners.reshape(-1, 2).astype(float), tuple(pattern_size))


# --------------------------------------------------------------------------------------------
# Camera calibration
# --------------------------------------------------------------------------------------------
def _per_view_rms(obj: np.ndarray, img_pts: np.ndarray, rvecs, tvecs, K, dist) -> np.ndarray:
    out = []
    for ip, r, t in zip(img_pts, rvecs, tvecs):
        proj, _ = cv2.projectPoints(obj, np.asarray(r, float).reshape(3, 1), np.asarray(t, float).reshape(3, 1), K, dist)
        out.append(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - ip) ** 2, axis=1))))
    return np.array(out)


def calibrate_chessboard(
    images: Sequence[np.ndarray],
    pattern_size: tuple[int, int] = (9, 6),
    square_size: float = 0.025,
    flags: int = 0,
    image_names: Sequence[str] | None = None,
    min_views: int = 3,
    subpix_window: int | None = None,
    aspect_ratio: float = 1.0,
) -> CalibrationResult:
    """Calibrate a camera (Zhang's method) from chessboard photographs.

    Args:
        images: list of (H, W) grayscale or (H, W, 3) BGR images of one size.
        pattern_size: inner corners (per row, rows).
        square_size: printed square side, metres (sets the unit of the translations).
        flags: ``cv2.CALIB_*`` flags, e.g. ``cv2.CALIB_FIX_ASPECT_RATIO``.
        image_names: names used in messages and in ``used``/``rejected`` (default ``image[i]``).
        min_views: fewest views with a detected board needed to calibrate.
        subpix_window: corner refinement window, see :func:`detect_chessboard`.
        aspect_ratio: fx/fy kept fixed when ``flags`` has ``CALIB_FIX_ASPECT_RATIO``.

    Returns:
        The calibration; views without a detected board are listed in ``rejected``.

    Raises:
        CalibrationError: no images, images of different sizes, no board in any image, or fewer
            than ``min_views`` usable views (the message names the images).
    """
    grays, names, size = _check_images(images, image_names, "calibration")
    if not square_size > 0:
        raise CalibrationError(f"calibration: square_size must be > 0 metres, got {square_size}")
    obj = chessboard_object_points(pattern_size, square_size)
    used, rejected, pts = [], {}, []
    for g, n in zip(grays, names):
        c = detect_chessboard(g, pattern_size, subpix_window)
        if c is None:
            rejected[n] = f"no {pattern_size[0]}x{pattern_size[1]} chessboard found"
            continue
        used.append(n)
        pts.append(c)
    if not used:
        raise CalibrationError(
            f"calibration: no {pattern_size[0]}x{pattern_size[1]} chessboard found in any image: {', '.join(names)}"
        )
    if len(used) < min_views:
        raise CalibrationError(
            f"calibration: only {len(used)} view(s) with a chessboard ({', '.join(used)}), need at least {min_views}; "
            f"rejected: {', '.join(f'{k} ({v})' for k, v in rejected.items()) or 'none'}"
        )
    K0 = np.eye(3)
    if flags & cv2.CALIB_FIX_ASPECT_RATIO:
        K0[0, 0] = float(aspect_ratio)
    obj32 = [obj.astype(np.float32)] * len(pts)
    img32 = [p.astype(np.float32).reshape(-1, 1, 2) for p in pts]
    _five_coefficient_model(flags, "calibrate_chessboard")
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj32, img32, size, K0, np.zeros(5), flags=flags)
    dist = np.asarray(dist, float).ravel()[:5]
    per_view = _per_view_rms(obj, np.array(pts), rvecs, tvecs, K, dist)
    return CalibrationResult(
        K=np.asarray(K, float),
        dist=np.pad(dist, (0, 5 - dist.size)),
        rms=float(rms),
        image_size=size,
        rvecs=np.array([np.ravel(r) for r in rvecs], float),
        tvecs=np.array([np.ravel(t) for t in tvecs], float),
        per_view_rms=per_view,
        used=used,
        rejected=rejected,
        object_points=obj,
        image_points=np.array(pts),
        flags=int(flags),
        pattern_size=(int(pattern_size[0]), int(pattern_size[1])),
        square_size=float(square_size),
    )


def calibrate_camera_from_target(
    images: Sequence[np.ndarray],
    target: ChessboardTarget = ChessboardTarget(),
    flags: int = 0,
    image_names: Sequence[str] | None = None,
    min_views: int = 3,
) -> CalibrationResult:
    """Calibrate a camera from images of a :class:`ChessboardTarget` (printed side visible).

    Args:
        images: (H, W) images of the target at several poses, projector dark.
        target: the target's geometry.
        flags: ``cv2.CALIB_*`` flags.
        image_names: names for messages and bookkeeping.
        min_views: fewest usable views.

    Returns:
        K, distortion and the board -> camera pose of each used view (see :class:`CalibrationResult`).
    """
    return calibrate_chessboard(images, target.pattern_size, target.square_size, flags, image_names, min_views)


def _board_to_world(board_to_world: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    if board_to_world is None:
        return np.eye(3), np.zeros(3)
    T = np.asarray(board_to_world, float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise CalibrationError(f"board_to_world must be a finite 4x4 rigid transform, got shape {T.shape}")
    Rw = T[:3, :3]
    if not np.allclose(Rw @ Rw.T, np.eye(3), atol=1e-6) or abs(np.linalg.det(Rw) - 1) > 1e-6:
        raise CalibrationError("board_to_world: the 3x3 block is not a rotation matrix")
    return Rw, T[:3, 3].copy()


def _world_pose(R_bc: np.ndarray, t_bc: np.ndarray, board_to_world: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    # X_c = R_bc X_b + t_bc, X_w = Rw X_b + tw  =>  X_c = R_bc Rw^T X_w + (t_bc - R_bc Rw^T tw)
    Rw, tw = _board_to_world(board_to_world)
    R = R_bc @ Rw.T
    return R, t_bc - R @ tw


def camera_from_calibration(
    result: CalibrationResult, view: int | str = 0, board_to_world: np.ndarray | None = None
) -> PinholeCamera:
    """The calibrated camera with its world frame defined by the target at one view.

    Args:
        result: a camera calibration.
        view: index into ``result.used`` or an image name: the pose at which the target defines
            the scene's world frame.
        board_to_world: optional (4, 4) rigid transform mapping board-frame points to the world
            frame wanted (e.g. to make z point up); identity by default.

    Returns:
        A :class:`PinholeCamera` with ``x_cam = R X_world + t``.
    """
    R_bc, t_bc = result.pose(view)
    R, t = _world_pose(R_bc, t_bc, board_to_world)
    w, h = result.image_size
    return PinholeCamera(result.K, R, t, w, h, result.dist)


# --------------------------------------------------------------------------------------------
# Geometry helpers
# --------------------------------------------------------------------------------------------
def undistort_normalized(xd: np.ndarray, yd: np.ndarray, dist: np.ndarray, iterations: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Invert OpenCV's distortion on normalised coordinates by fixed-point iteration.

    Args:
        xd, yd: distorted normalised coordinates (any equal shapes).
        dist: (5,) ``k1, k2, p1, p2, k3``.
        iterations: fixed-point iterations (30 reaches < 1e-8 for ordinary lenses).

    Returns:
        Undistorted normalised ``x, y`` of the same shapes.
    """
    d = np.zeros(5)
    dd = np.asarray(dist, float).ravel()
    d[: min(5, dd.size)] = dd[:5]
    if not np.any(d):
        return np.asarray(xd, float).copy(), np.asarray(yd, float).copy()
    k1, k2, p1, p2, k3 = d
    x, y = np.asarray(xd, float).copy(), np.asarray(yd, float).copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
        dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        x = (xd - dx) / radial
        y = (yd - dy) / radial
    return x, y


def pixel_rays(uv: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """(N, 3) camera-frame ray directions ``(x, y, 1)`` of distorted pixels ``uv`` (N, 2)."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    yd = (uv[:, 1] - K[1, 2]) / K[1, 1]
    xd = (uv[:, 0] - K[0, 2] - K[0, 1] * yd) / K[0, 0]
    x, y = undistort_normalized(xd, yd, dist)
    return np.stack([x, y, np.ones_like(x)], axis=1)


def intersect_board(rays: np.ndarray, R_bc: np.ndarray, t_bc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Intersect camera rays with the board plane ``z_board = 0``.

    Args:
        rays: (..., 3) directions in the camera frame (camera centre at the origin).
        R_bc, t_bc: board -> camera rotation (3, 3) and translation (3,), metres.

    Returns:
        ``(X_cam, X_board)``: (..., 3) intersection points in the camera and board frames;
        rays parallel to the plane or meeting it behind the camera give NaN.
    """
    n = R_bc[:, 2]
    denom = rays @ n
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (t_bc @ n) / denom
    s = np.where((np.abs(denom) > 1e-12) & (s > 0), s, np.nan)
    Xc = rays * s[..., None]
    Xb = (Xc - t_bc) @ R_bc  # R^T (Xc - t)
    return Xc, Xb


# --------------------------------------------------------------------------------------------
# Projector calibration
# --------------------------------------------------------------------------------------------
def _projected_light(target_img: np.ndarray, pattern_img: np.ndarray) -> np.ndarray:
    """uint8 image of the projected light only (projector-on minus projector-off, stretched)."""
    d = pattern_img.astype(float) - target_img.astype(float)
    d = np.clip(d, 0, None)
    hi = np.percentile(d, 99.5)
    if hi <= 0:
        return np.zeros_like(target_img)
    return np.clip(np.rint(255.0 * d / hi), 0, 255).astype(np.uint8)


def board_pose(
    camera: CalibrationResult, image: np.ndarray, name: str = "image"
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Pose of the printed board in one image with the calibrated camera (PnP, LM-refined).

    Args:
        camera: calibration giving K, distortion and the board's ``pattern_size``/``square_size``.
        image: (H, W) image of the board, projector dark.
        name: image name for messages.

    Returns:
        ``(R, t, rms_px)``: board -> camera rotation (3, 3), translation (3,) metres and the
        view's RMS reprojection error in pixels; ``None`` when the board is not found.
    """
    g = _as_gray_u8(image, name)
    w, h = camera.image_size
    if g.shape != (h, w):
        raise CalibrationError(f"image '{name}' is {g.shape[1]}x{g.shape[0]}, expected {w}x{h} like the camera calibration")
    c = detect_chessboard(g, camera.pattern_size)
    if c is None:
        return None
    obj = chessboard_object_points(camera.pattern_size, camera.square_size)
    ok, rvec, tvec = cv2.solvePnP(obj, c, camera.K, camera.dist, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        return None
    rvec, tvec = cv2.solvePnPRefineLM(obj, c, camera.K, camera.dist, rvec, tvec)
    err = _per_view_rms(obj, c[None], [rvec], [tvec], camera.K, camera.dist)[0]
    R, _ = cv2.Rodrigues(rvec)
    return R, np.ravel(tvec).astype(float), float(err)


#: Default projector model: no lens distortion. A projected pattern usually covers only part of
#: the projector image, which does not constrain distortion; pass other flags to estimate it.
PROJECTOR_FLAGS: int = cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3


def calibrate_projector(
    camera: CalibrationResult,
    target_images: Sequence[np.ndarray],
    pattern_images: Sequence[np.ndarray | None],
    pattern: ProjectorPattern | Sequence[ProjectorPattern | None],
    image_names: Sequence[str] | None = None,
    flags: int = PROJECTOR_FLAGS,
    min_views: int = 3,
    joint: bool | None = None,
) -> ProjectorCalibration:
    """Calibrate a projector from its chessboard pattern cast onto the target (inverse camera).

    For each view the target's pose is found from its printed board with the calibrated camera
    (PnP). The projected corners are found in the difference image (projector on minus off),
    their camera rays are intersected with the target plane, and the 3-D points are matched with
    the pattern's projector pixels: projector intrinsics by Zhang's method on the per-view
    planar points, then the camera -> projector pose by PnP over all views' points in the camera
    frame (non-planar, so the pose is well determined).

    Args:
        camera: calibration of the camera that took the images.
        target_images: per view, the target with the projector dark.
        pattern_images: per view, the same pose and exposure with the pattern projected
            (``None`` for a view without one).
        pattern: the projected pattern (projector resolution, corners in projector pixels), or
            one per view (``None`` where no pattern is cast), or one per view with a pattern
            image, in order (e.g. :func:`spread_patterns` as given to
            :func:`film_calibration_target`); all of one projector resolution.
        image_names: names of the views (default ``projector[i]``).
        flags: ``cv2.CALIB_*`` flags for the projector intrinsics (default :data:`PROJECTOR_FLAGS`).
        min_views: fewest views with both the board and the projected pattern found.
        joint: refine the intrinsics and the one camera -> projector pose together on all views'
            points (kept only where it lowers the reprojection error). ``None`` (default): when
            the views' patterns sit at different places in the projector's image. With one
            pattern at one place every view's points lie in one narrow bundle of projector rays,
            along which focal length and distance trade off, and the joint refinement drifts
            along that valley (27 mm off in a test scene where the per-view estimate is 0.5 mm
            off); spread over the image they determine both (docs/cloth_study.md, "Studio design").

    Returns:
        Projector intrinsics and camera -> projector pose.

    Raises:
        CalibrationError: mismatched inputs, or fewer than ``min_views`` usable views (the
            message names the rejected views and why).
    """
    if len(pattern_images) != len(target_images):
        raise CalibrationError(
            f"projector: {len(target_images)} target images but {len(pattern_images)} pattern images (one per view needed)"
        )
    if image_names is None:
        image_names = [f"projector[{i}]" for i in range(len(target_images))]
    names = [str(n) for n in image_names]
    if len(names) != len(target_images):
        raise CalibrationError(f"projector: {len(target_images)} views but {len(names)} image_names")
    n_lit = sum(img is not None for img in pattern_images)
    if not isinstance(pattern, ProjectorPattern) and pattern is not None and len(list(pattern)) == n_lit != len(target_images):
        it = iter(pattern)  # one pattern per view with a pattern image, in order
        pattern = [next(it) if img is not None else None for img in pattern_images]
    pats = _patterns_per_view(pattern, len(target_images), "projector")
    lit = [p for p, img in zip(pats, pattern_images) if img is not None]
    if any(p is None for p in lit):
        raise CalibrationError("projector: a view with a pattern image has no pattern (None)")
    if len({(p.width, p.height) for p in lit}) > 1:
        raise CalibrationError(f"projector: the views' patterns disagree on the projector's resolution: {sorted({(p.width, p.height) for p in lit})}")
    w, h = camera.image_size
    obj_b, img_p, pts_c, used, rejected = [], [], [], [], {}
    used_pats: list[ProjectorPattern] = []
    poses_bc: list[tuple[np.ndarray, np.ndarray]] = []
    for n, timg, pimg, pat in zip(names, target_images, pattern_images, pats):
        if pimg is None:
            continue
        corners_p = pat.corners()
        nx, ny = pat.pattern_size
        pose = board_pose(camera, timg, n)
        if pose is None:
            rejected[n] = f"printed {camera.pattern_size[0]}x{camera.pattern_size[1]} board not found"
            continue
        R_bc, t_bc, _ = pose
        tg, pg = _as_gray_u8(timg, n), _as_gray_u8(pimg, f"{n} (pattern)")
        if pg.shape != (h, w):
            raise CalibrationError(f"projector: pattern image of view '{n}' is {pg.shape[1]}x{pg.shape[0]}, expected {w}x{h}")
        c = detect_chessboard(_projected_light(tg, pg), (nx, ny), subpix_window=None, thorough=True)
        if c is None:
            rejected[n] = f"projected {nx}x{ny} pattern not found"
            continue
        Xc, Xb = intersect_board(pixel_rays(c, camera.K, camera.dist), R_bc, t_bc)
        if not np.all(np.isfinite(Xc)):
            rejected[n] = "projected corners do not meet the target plane"
            continue
        used.append(n)
        used_pats.append(pat)
        obj_b.append(Xb)
        img_p.append(corners_p)
        pts_c.append(Xc)
        poses_bc.append((R_bc, t_bc))
    if len(used) < min_views:
        raise CalibrationError(
            f"projector: only {len(used)} view(s) with board and projected pattern found ({', '.join(used) or 'none'}), "
            f"need at least {min_views}; rejected: {', '.join(f'{k} ({v})' for k, v in rejected.items()) or 'none'}"
        )
    size_p = (lit[0].width, lit[0].height)
    obj32 = [np.column_stack([o[:, :2], np.zeros(len(o))]).astype(np.float32) for o in obj_b]
    img32 = [p.astype(np.float32).reshape(-1, 1, 2) for p in img_p]
    _five_coefficient_model(flags, "projector calibration")
    _, Kp, dp, rv_bp, tv_bp = cv2.calibrateCamera(obj32, img32, size_p, None, None, flags=flags)
    dp = np.asarray(dp, float).ravel()[:5]
    dp = np.pad(dp, (0, 5 - dp.size))
    # Camera -> projector pose: start from the per-view estimates (board -> projector composed
    # with camera -> board), averaged on the rotation manifold, then refine on all points.
    Rs, ts = [], []
    for rvb, tvb, (Rbc, tbc) in zip(rv_bp, tv_bp, poses_bc):
        Rbp, _ = cv2.Rodrigues(np.asarray(rvb, float))
        Rpc = Rbp @ Rbc.T
        Rs.append(Rpc)
        ts.append(np.ravel(tvb) - Rpc @ tbc)
    U, _, Vt = np.linalg.svd(np.sum(Rs, axis=0))
    R0 = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    rvec, _ = cv2.Rodrigues(R0)
    tvec = np.median(ts, axis=0).reshape(3, 1)
    Xall = np.concatenate(pts_c)
    uall = np.concatenate(img_p)
    rvec, tvec = cv2.solvePnPRefineLM(Xall, uall, Kp, dp, rvec, tvec)
    if joint is None:  # on the views used (rejections may leave one place only)
        joint = len({p._origin() for p in used_pats}) > 1
    if joint:
        # One projector pose serves every view: refine intrinsics and that pose together on all
        # views' points in the camera frame (a non-planar 3-D target), instead of intrinsics from
        # each view's small planar patch with a free pose per view.
        # Kept only when it lowers the reprojection error (from a poor start it can run away).
        def _rms(K_, d_, r_, t_) -> float:
            pr, _ = cv2.projectPoints(Xall, r_, t_, K_, d_)
            e = np.sum((pr.reshape(-1, 2) - uall) ** 2, axis=1)
            return float(np.sqrt(e.mean())) if np.all(np.isfinite(e)) else np.inf

        try:
            _, Kj, dj, rv, tv = cv2.calibrateCamera(
                [Xall.astype(np.float32)], [uall.astype(np.float32).reshape(-1, 1, 2)], size_p, Kp.copy(), dp.copy(),
                rvecs=[rvec.copy()], tvecs=[tvec.copy()], flags=flags | cv2.CALIB_USE_INTRINSIC_GUESS)
            dj = np.pad(np.asarray(dj, float).ravel()[:5], (0, max(0, 5 - np.asarray(dj).size)))
            rj, tj = np.asarray(rv[0], float).reshape(3, 1), np.asarray(tv[0], float).reshape(3, 1)
            ok = np.all(np.isfinite(Kj)) and Kj[0, 0] > 0 and Kj[1, 1] > 0 and _rms(Kj, dj, rj, tj) <= _rms(Kp, dp, rvec, tvec)
        except cv2.error:
            ok = False
        if ok:
            Kp, dp, rvec, tvec = Kj, dj, rj, tj
    Rp, _ = cv2.Rodrigues(rvec)
    proj, _ = cv2.projectPoints(Xall, rvec, tvec, Kp, dp)
    res = np.sum((proj.reshape(-1, 2) - uall) ** 2, axis=1)
    counts = np.cumsum([0] + [len(p) for p in pts_c])
    per_view = np.array([np.sqrt(res[a:b].mean()) for a, b in zip(counts[:-1], counts[1:])])
    return ProjectorCalibration(
        K=np.asarray(Kp, float),
        dist=dp,
        R=Rp,
        t=np.ravel(tvec).astype(float),
        image_size=size_p,
        rms=float(np.sqrt(res.mean())),
        per_view_rms=per_view,
        used=used,
        rejected=rejected,
        points_camera=Xall,
        points_projector=uall,
    )


def projector_from_calibration(
    camera: CalibrationResult,
    projector: ProjectorCalibration,
    view: int | str = 0,
    board_to_world: np.ndarray | None = None,
) -> PinholeCamera:
    """The projector as a :class:`PinholeCamera` in the world frame of the target at ``view``."""
    R_bc, t_bc = camera.pose(view)
    R_wc, t_wc = _world_pose(R_bc, t_bc, board_to_world)  # world -> camera
    R = projector.R @ R_wc
    t = projector.R @ t_wc + projector.t
    w, h = projector.image_size
    return PinholeCamera(projector.K, R, t, w, h, projector.dist)


# --------------------------------------------------------------------------------------------
# Stage-level entry
# --------------------------------------------------------------------------------------------
def calibrate_scene(
    target_images: Sequence[np.ndarray],
    projector_images: Sequence[np.ndarray | None] | None = None,
    *,
    target: ChessboardTarget = ChessboardTarget(),
    pattern: ProjectorPattern | Sequence[ProjectorPattern | None] | None = None,
    reference_view: int | str = 0,
    image_names: Sequence[str] | None = None,
    flags: int = 0,
    board_to_world: np.ndarray | None = None,
    min_views: int = 3,
) -> dict:
    """Calibrate the camera (and the projector, when its images are given) of one scene.

    Args:
        target_images: images of the target at V poses, projector dark.
        projector_images: images at the same poses with the projector casting ``pattern``
            (``None`` entries for views without), or ``None`` when the scene has no projector.
        target: geometry of the printed target.
        pattern: the projected pattern (required with ``projector_images``), or one per view
            (see :func:`calibrate_projector`).
        reference_view: the view (index into the used views or image name) whose target pose
            defines the world frame.
        image_names: names of the views (default ``calibration[i]``).
        flags: ``cv2.CALIB_*`` flags of the camera calibration.
        board_to_world: optional (4, 4) board -> world transform (default identity).
        min_views: fewest usable views.

    Returns:
        ``calibration.yaml``-ready dict: ``camera`` (:meth:`PinholeCamera.to_dict`), ``rms_px``,
        ``n_views``, ``views_used``, ``views_rejected``, ``reference_view`` and, with a
        projector, ``projector`` (a camera dict), ``projector_rms_px``, ``projector_n_views``.
    """
    if image_names is None:
        image_names = [f"calibration[{i}]" for i in range(len(target_images))]
    cam = calibrate_camera_from_target(target_images, target, flags, image_names, min_views)
    ref = cam.used[cam.view_index(reference_view)]
    out: dict = {
        "camera": camera_from_calibration(cam, ref, board_to_world).to_dict(),
        "rms_px": float(cam.rms),
        "n_views": cam.n_views,
        "views_used": list(cam.used),
        "views_rejected": dict(cam.rejected),
        "reference_view": ref,
    }
    if projector_images is not None:
        if pattern is None:
            raise CalibrationError("calibrate_scene: projector_images given but no projector 'pattern'")
        pc = calibrate_projector(cam, target_images, projector_images, pattern, image_names, min_views=min_views)
        out["projector"] = projector_from_calibration(cam, pc, ref, board_to_world).to_dict()
        out["projector_rms_px"] = float(pc.rms)
        out["projector_n_views"] = len(pc.used)
        out["projector_views_rejected"] = dict(pc.rejected)
    return out


# --------------------------------------------------------------------------------------------
# Synthetic footage of the target
# --------------------------------------------------------------------------------------------
def board_poses_facing_camera(
    n: int,
    rng: np.random.Generator,
    anchor_board: np.ndarray,
    anchor_camera: np.ndarray,
    max_tilt_deg: float = 30.0,
    min_tilt_deg: float = 10.0,
    max_roll_deg: float = 10.0,
    jitter: float = 0.03,
    roll_offset_deg: float = 0.0,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Random board -> camera poses with the printed face towards the camera.

    The board point ``anchor_board`` (3,) is placed near ``anchor_camera`` (3,) (camera frame,
    metres, jittered by up to ``jitter`` m per axis). The board is tilted out of the
    fronto-parallel plane by an angle uniform in [``min_tilt_deg``, ``max_tilt_deg``] about a
    random in-plane axis (fronto-parallel views do not constrain the focal length), and rolled
    about the viewing axis by up to ``max_roll_deg`` about ``roll_offset_deg`` (180: the board
    held upside down).

    Returns:
        ``n`` pairs ``(R, t)`` with ``X_cam = R X_board + t``.
    """
    if not 0 <= min_tilt_deg <= max_tilt_deg < 80:
        raise CalibrationError(f"board poses: need 0 <= min_tilt_deg <= max_tilt_deg < 80, got {min_tilt_deg}, {max_tilt_deg}")
    poses = []
    for _ in range(int(n)):
        tilt = np.deg2rad(rng.uniform(min_tilt_deg, max_tilt_deg))
        phi = rng.uniform(0, 2 * np.pi)
        roll = np.deg2rad(roll_offset_deg + rng.uniform(-max_roll_deg, max_roll_deg))
        R_tilt, _ = cv2.Rodrigues(tilt * np.array([np.cos(phi), np.sin(phi), 0.0]))
        R_roll, _ = cv2.Rodrigues(np.array([0.0, 0.0, roll]))
        R = R_tilt @ R_roll
        t = np.asarray(anchor_camera, float) + rng.uniform(-jitter, jitter, 3) - R @ np.asarray(anchor_board, float)
        poses.append((R, t))
    return poses


_RAY_CACHE: dict[tuple, np.ndarray] = {}


def _supersampled_rays(camera: PinholeCamera, ss: int) -> np.ndarray:
    """(H*ss, W*ss, 3) camera-frame rays through sub-pixel samples of the distorted image.

    The last map is cached (keyed by intrinsics, distortion, size and ``ss``): rendering many
    views with one camera inverts the lens distortion once.
    """
    key = (camera.K.tobytes(), camera.dist.tobytes(), camera.width, camera.height, int(ss))
    if key in _RAY_CACHE:
        return _RAY_CACHE[key]
    _RAY_CACHE.clear()
    # Undistort on a pixel grid with a one-pixel border, then interpolate bilinearly to the
    # sub-pixel samples (cv2.resize maps dst x to src (x + 0.5) / ss - 0.5: the sample offsets).
    u, v = np.meshgrid(np.arange(-1, camera.width + 1, dtype=float), np.arange(-1, camera.height + 1, dtype=float))
    coarse = pixel_rays(np.stack([u.ravel(), v.ravel()], 1), camera.K, camera.dist).reshape(u.shape + (3,))
    if ss == 1:
        rays = np.ascontiguousarray(coarse[1:-1, 1:-1])
    else:
        fine = cv2.resize(coarse[..., :2], (u.shape[1] * ss, u.shape[0] * ss), interpolation=cv2.INTER_LINEAR)
        fine = fine[ss:-ss, ss:-ss]
        rays = np.concatenate([fine, np.ones(fine.shape[:2] + (1,))], axis=2)
    rays.flags.writeable = False
    _RAY_CACHE[key] = rays
    return rays


def render_target_views(
    camera: PinholeCamera,
    poses: Sequence[tuple[np.ndarray, np.ndarray]],
    target: ChessboardTarget,
    rng: np.random.Generator,
    *,
    projector: PinholeCamera | None = None,
    pattern: ProjectorPattern | Sequence[ProjectorPattern | None] | None = None,
    ambient: float = 0.55,
    projector_gain: float = 0.45,
    blur_sigma_px: float = 0.7,
    noise_sigma: float = 2.0,
    supersample: int = 1,
) -> list[np.ndarray]:
    """Render 8-bit grayscale images of the target as seen by ``camera`` at several poses.

    Ray-plane intersection for ``supersample`` x ``supersample`` samples per pixel through the
    camera's distorted lens (so the images carry its distortion); each sample carries the box
    average of the board texture and of the projected pattern over its footprint (analytic edge
    ramps, so edges are not aliased even at ``supersample=1``); samples are averaged per pixel,
    then a Gaussian optical blur and Gaussian sensor noise are applied. Radiance is
    ``albedo * (ambient + projector_gain * pattern * cos(incidence))``, with the pattern value
    found by projecting each board point into the projector.

    Args:
        camera: the camera; its ``R, t`` are ignored (poses are board -> camera).
        poses: V pairs ``(R, t)`` board -> camera, metres.
        target: the target.
        rng: random generator for the noise.
        projector: the projector with ``R, t`` camera frame -> projector frame; ``None``: dark.
        pattern: the projected pattern (required with ``projector``), or one per pose.
        ambient: ambient irradiance (exposure-scaled, 1.0 saturates white paper).
        projector_gain: projector irradiance at normal incidence.
        blur_sigma_px: optical blur, pixels (0: none).
        noise_sigma: sensor noise standard deviation, grey levels.
        supersample: samples per pixel along each axis (edges are box-filtered analytically,
            so 1 already gives corners within 0.1 px of the true projection).

    Returns:
        V images (H, W) uint8.
    """
    pats = _patterns_per_view(pattern, len(poses), "render_target_views")
    if projector is not None and any(p is None for p in pats):
        raise CalibrationError("render_target_views: a projector needs a 'pattern' for every pose")
    if supersample < 1:
        raise CalibrationError(f"render_target_views: supersample must be >= 1, got {supersample}")
    rays = _supersampled_rays(camera, int(supersample))
    H, W, ss = camera.height, camera.width, int(supersample)
    images = []
    for (R, t), pat in zip(poses, pats):
        R = np.asarray(R, float)
        t = np.asarray(t, float).ravel()
        Xc, Xb = intersect_board(rays, R, t)
        hit = np.isfinite(Xb[..., 0])
        # board footprint of one sample: (depth / f / ss) / sqrt(cos incidence), isotropic
        with np.errstate(invalid="ignore", divide="ignore"):
            cos_c = np.abs(rays @ R[:, 2]) / np.linalg.norm(rays, axis=-1)
            foot = Xc[..., 2] / (camera.K[0, 0] * ss) / np.sqrt(np.maximum(cos_c, 0.05))
            alb = np.where(hit, target.albedo(Xb[..., 0], Xb[..., 1], foot), target.background)
        irr = np.full(Xb.shape[:2], float(ambient))
        if projector is not None:
            Xp = Xc @ projector.R.T + projector.t
            z = Xp[..., 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                x, y = Xp[..., 0] / z, Xp[..., 1] / z
                if np.any(projector.dist):
                    x, y = distort_normalized(x, y, projector.dist)
                Kp = projector.K
                up = Kp[0, 0] * x + Kp[0, 1] * y + Kp[0, 2]
                vp = Kp[1, 1] * y + Kp[1, 2]
                inside = hit & (z > 0) & np.isfinite(up) & np.isfinite(vp)
                # footprint of the camera sample in projector pixels
                val = np.where(inside, pat.radiance(np.where(inside, up, -1e6), np.where(inside, vp, -1e6), foot * Kp[0, 0] / np.abs(z)), 0.0)
            # cos of incidence: board normal vs direction to the projector centre (camera frame)
            to_p = (-projector.R.T @ projector.t) - Xc
            with np.errstate(divide="ignore", invalid="ignore"):
                cosi = np.abs(to_p @ R[:, 2]) / np.linalg.norm(to_p, axis=-1)
            irr = irr + projector_gain * np.where(inside, val * cosi, 0.0)
        rad = np.clip(alb * irr, 0.0, None)
        img = rad.reshape(H, ss, W, ss).mean(axis=(1, 3)) * 255.0
        if blur_sigma_px > 0:
            img = cv2.GaussianBlur(img, (0, 0), blur_sigma_px)
        img = img + rng.normal(0.0, noise_sigma, img.shape)
        images.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    return images


def _visible(camera: PinholeCamera, R: np.ndarray, t: np.ndarray, pts_board: np.ndarray, margin: float) -> bool:
    cam = PinholeCamera(camera.K, R, t, camera.width, camera.height, camera.dist)
    if np.any(cam.to_camera(pts_board)[:, 2] <= 0.05):
        return False
    uv = cam.project(pts_board)
    return bool(
        np.all(np.isfinite(uv))
        and np.all((uv[:, 0] >= margin) & (uv[:, 0] <= camera.width - 1 - margin))
        and np.all((uv[:, 1] >= margin) & (uv[:, 1] <= camera.height - 1 - margin))
    )


def film_calibration_target(
    camera: PinholeCamera,
    rng: np.random.Generator,
    *,
    target: ChessboardTarget = ChessboardTarget(),
    projector: PinholeCamera | None = None,
    pattern: ProjectorPattern | Sequence[ProjectorPattern] | None = None,
    n_views: int = 10,
    n_projector_views: int = 8,
    board_to_world: np.ndarray | None = None,
    max_tilt_deg: float = 30.0,
    min_tilt_deg: float = 12.0,
    supersample: int = 1,
    blur_sigma_px: float = 0.7,
    noise_sigma: float = 2.0,
    max_tries: int = 200,
) -> tuple[list[np.ndarray], list[np.ndarray | None], list[str]]:
    """Film a calibration session of a synthetic scene (the reality side of calibration).

    Views, in order: optionally the reference view (the target at ``board_to_world`` in the
    scene's world frame; it then defines the world frame for :func:`calibrate_scene` with
    ``reference_view=0``), ``n_views`` camera views with the printed board spread over the
    image, and, with a projector, ``n_projector_views`` poses where the projector's pattern
    lands on the blank part of the target (two images each: projector dark, projector on).

    Args:
        camera: the scene camera in world coordinates (``R, t`` world -> camera).
        rng: random generator (poses and noise).
        target: the calibration target.
        projector: the projector in world coordinates (``R, t`` world -> projector), or ``None``.
        pattern: the pattern it casts (required with ``projector``), or one per projector view
            (e.g. :func:`spread_patterns`).
        n_views: camera-only views.
        n_projector_views: views with the pattern projected.
        board_to_world: (4, 4) pose of the target in the world for the reference view, or
            ``None`` for no reference view.
        max_tilt_deg, min_tilt_deg: range of board tilts out of the fronto-parallel plane.
        supersample, blur_sigma_px, noise_sigma: image formation, see :func:`render_target_views`.
        max_tries: attempts to draw a pose that keeps the features in view.

    Returns:
        ``(target_images, projector_images, names)``: uint8 images; ``projector_images[i]`` is
        ``None`` for views without the projector. Inputs of :func:`calibrate_scene`.

    Raises:
        CalibrationError: the reference pose does not show the board, or no valid pose is found.
    """
    if projector is not None and pattern is None:
        raise CalibrationError("film_calibration_target: a projector needs a 'pattern'")
    nx, ny = target.pattern_size
    s = target.square_size
    printed = np.array([[-s, -s, 0], [nx * s, -s, 0], [nx * s, ny * s, 0], [-s, ny * s, 0]], float)
    printed_centre = np.array([(nx - 1) * s / 2, (ny - 1) * s / 2, 0.0])
    fx = camera.K[0, 0]
    poses: list[tuple[np.ndarray, np.ndarray]] = []
    names: list[str] = []
    with_projector: list[bool] = []
    if board_to_world is not None:
        Rw, tw = _board_to_world(board_to_world)
        R_bc, t_bc = camera.R @ Rw, camera.R @ tw + camera.t
        if not _visible(camera, R_bc, t_bc, printed, 2.0):
            raise CalibrationError("film_calibration_target: the printed board at 'board_to_world' is not fully in view")
        poses.append((R_bc, t_bc))
        names.append("reference")
        with_projector.append(False)
    # camera views: printed board about half the image wide, spread over the image
    z0 = fx * (nx + 1) * s / (0.5 * camera.width)
    for i in range(int(n_views)):
        for _ in range(max_tries):
            z = z0 * rng.uniform(0.8, 1.3)
            u = rng.uniform(0.25, 0.75) * camera.width
            v = rng.uniform(0.25, 0.75) * camera.height
            anchor = np.array([(u - camera.K[0, 2]) / fx * z, (v - camera.K[1, 2]) / camera.K[1, 1] * z, z])
            R, t = board_poses_facing_camera(1, rng, printed_centre, anchor, max_tilt_deg, min_tilt_deg, jitter=0.0)[0]
            if _visible(camera, R, t, printed, 4.0):
                break
        else:
            raise CalibrationError(f"film_calibration_target: no pose keeps the board in view after {max_tries} tries")
        poses.append((R, t))
        names.append(f"view{i:02d}")
        with_projector.append(False)
    proj_cam = None
    if projector is not None and n_projector_views > 0:
        # projector relative to the camera: x_p = R_pc x_c + t_pc
        R_pc = projector.R @ camera.R.T
        proj_cam = PinholeCamera(projector.K, R_pc, projector.t - R_pc @ camera.t, projector.width, projector.height, projector.dist)
        view_patterns = _patterns_per_view(pattern, int(n_projector_views), "film_calibration_target")
        x0, x1, y0, y1 = target.board_extent
        blank = (nx * s + s, x1, y0, y1)
        blank_centre = np.array([(blank[0] + blank[1]) / 2, (blank[2] + blank[3]) / 2, 0.0])
        fp = projector.K[0, 0]
        for i in range(int(n_projector_views)):
            q = view_patterns[i].corners()
            sq = view_patterns[i].square_px
            frame = np.array([q.min(0) - sq, [q.max(0)[0] + sq, q.min(0)[1] - sq], q.max(0) + sq, [q.min(0)[0] - sq, q.max(0)[1] + sq]])
            span_px = np.ptp(frame, axis=0)
            d = 0.7 * min((blank[1] - blank[0]) * fp / span_px[0], (blank[3] - blank[2]) * projector.K[1, 1] / span_px[1])
            # aim: this view's pattern centre's projector ray at distance d from the projector (camera
            # frame); an off-centre pattern may need the board nearer the projector, or held upside
            # down (its blank part left of the print), to keep the print in the camera's view, so
            # later tries draw the distance from [0.4, 1] d and turn the board by 0 or 180 degrees
            c = frame.mean(0)
            ray = np.linalg.solve(projector.K, np.array([c[0], c[1], 1.0]))
            ray /= np.linalg.norm(ray)
            for k in range(max_tries):
                early = k < max_tries // 4
                dk = d if early else d * rng.uniform(0.4, 1.0)
                aim = proj_cam.R.T @ (dk * ray - proj_cam.t)
                R, t = board_poses_facing_camera(1, rng, blank_centre, aim, max_tilt_deg, min_tilt_deg, jitter=0.03,
                                                 roll_offset_deg=0.0 if early else 180.0 * rng.integers(2))[0]
                if not _visible(camera, R, t, printed, 4.0):
                    continue
                rays_p = np.linalg.solve(projector.K, np.column_stack([frame, np.ones(4)]).T).T  # projector frame
                rays_c = rays_p @ proj_cam.R  # directions in the camera frame
                origin = proj_cam.center
                n = R[:, 2]
                sdist = ((t - origin) @ n) / (rays_c @ n)
                Xb = (origin + sdist[:, None] * rays_c - t) @ R
                inside = (sdist > 0) & (Xb[:, 0] >= blank[0]) & (Xb[:, 0] <= blank[1]) & (Xb[:, 1] >= blank[2]) & (Xb[:, 1] <= blank[3])
                if np.all(inside) and _visible(camera, R, t, Xb, 4.0):
                    break
            else:
                raise CalibrationError(
                    f"film_calibration_target: no pose puts the projected pattern on the blank target area after {max_tries} tries"
                )
            poses.append((R, t))
            names.append(f"projector{i:02d}")
            with_projector.append(True)
    kw = dict(blur_sigma_px=blur_sigma_px, noise_sigma=noise_sigma, supersample=supersample)
    target_images = render_target_views(camera, poses, target, rng, **kw)
    projector_images: list[np.ndarray | None] = [None] * len(poses)
    idx = [i for i, w in enumerate(with_projector) if w]
    if idx:
        lit = render_target_views(camera, [poses[i] for i in idx], target, rng, projector=proj_cam, pattern=view_patterns, **kw)
        for i, im in zip(idx, lit):
            projector_images[i] = im
    return target_images, projector_images, names
