"""The footage folder: what every estimator reads, and nothing about the unknowns.

Layout (documented in the README, so a user can drop in their own recording)::

    <footage>/
      frames/000000.png ...   one image per frame (PNG, 8-bit RGB or gray), or
      video.<ext>             one video file (webm/mp4/avi; timestamps read from the container)
      times.csv               one timestamp per frame in seconds (optional with a video file)
      calibration.yaml        {camera: {width, height, K, dist, R, t}, projector: {...} optional}
      meta.yaml               known inputs (object shape, mass, inertia, driven corners, ...)

The truth of a synthetic scene is written BESIDE the folder (``<footage>.truth.yaml``) by the
reality generator and is read only by scoring stages (:func:`read_truth`).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from vidsim.errors import FootageError
from vidsim.io.atomic import atomic_path, write_text, write_yaml
from vidsim.video.camera import CameraError, PinholeCamera

FRAME_DIR = "frames"
DEVICES = ("camera", "projector")
VIDEO_EXTS = (".webm", ".mp4", ".avi", ".mkv", ".mov")


@dataclass
class Footage:
    """A loaded footage folder.

    Attributes:
        frames: (T, H, W, 3) uint8 RGB frames.
        times: (T,) strictly increasing frame times in seconds.
        cameras: calibrated devices by name (``camera``, optionally ``projector``).
        meta: known inputs from ``meta.yaml``.
        path: the folder it came from.
    """

    frames: np.ndarray
    times: np.ndarray
    cameras: dict[str, PinholeCamera]
    meta: dict[str, Any]
    path: Path | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def camera(self) -> PinholeCamera:
        return self.cameras["camera"]


def truth_path(folder: str | os.PathLike) -> Path:
    """Where the truth of a synthetic footage folder lives (beside it, never inside)."""
    folder = Path(folder)
    return folder.parent / f"{folder.name}.truth.yaml"


def recording_path(folder: str | os.PathLike) -> Path:
    """Where the reality stages' Rerun recording of a synthetic footage folder lives: beside it, like
    the truth, because it shows the truth (true masks, meshes, flow) next to the footage; a footage
    folder holds only what a real recording would."""
    folder = Path(folder)
    return folder.parent / f"{folder.name}.reality.rrd"


# --------------------------------------------------------------------------- writing
def write_footage(
    folder: str | os.PathLike,
    frames: np.ndarray,
    times: np.ndarray,
    cameras: dict[str, PinholeCamera],
    meta: dict[str, Any],
) -> Path:
    """Write a footage folder (frames as PNG, times, calibration, meta), each file atomically.

    Args:
        folder: destination folder (created).
        frames: (T, H, W, 3) or (T, H, W) uint8.
        times: (T,) seconds, strictly increasing.
        cameras: name -> calibrated camera; must contain ``camera``.
        meta: known inputs; must not contain truth.
    """
    folder = Path(folder)
    frames = np.asarray(frames)
    times = np.asarray(times, dtype=float)
    if frames.ndim not in (3, 4) or frames.dtype != np.uint8:
        raise FootageError(f"{folder}: frames must be uint8 (T,H,W[,3]), got {frames.dtype} {frames.shape}")
    if times.shape != (frames.shape[0],):
        raise FootageError(f"{folder}: times must have one entry per frame ({frames.shape[0]}), got {times.shape}")
    if "camera" not in cameras:
        raise FootageError(f"{folder}: cameras must contain 'camera'")
    fdir = folder / FRAME_DIR
    fdir.mkdir(parents=True, exist_ok=True)
    for i, img in enumerate(frames):
        bgr = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
        with atomic_path(fdir / f"{i:06d}.png") as tmp:
            if not cv2.imwrite(str(tmp), bgr):
                raise FootageError(f"{fdir / f'{i:06d}.png'}: could not encode frame")
    write_text(folder / "times.csv", "time_s\n" + "".join(f"{t:.9f}\n" for t in times))
    write_yaml(folder / "calibration.yaml", {k: v.to_dict() for k, v in cameras.items()})
    write_yaml(folder / "meta.yaml", {**meta, "n_frames": int(frames.shape[0])})
    return folder


def write_truth(folder: str | os.PathLike, truth: dict[str, Any]) -> Path:
    """Write the truth of a synthetic footage folder beside it (see :func:`truth_path`)."""
    p = truth_path(folder)
    write_yaml(p, truth)
    return p


# --------------------------------------------------------------------------- reading
def load_yaml(path: str | os.PathLike, error: type[Exception] = FootageError, what: str = "file",
              mapping: bool = False) -> Any:
    """A YAML file's content; ``error`` (a one-line message naming the file) when it is missing,
    not text (random bytes), not valid YAML, or, with ``mapping``, not a mapping (empty: ``{}``)."""
    path = Path(path)
    if not path.is_file():
        raise error(f"{path}: {what} is missing")
    try:
        doc = yaml.safe_load(path.read_text())
    except UnicodeDecodeError as e:
        raise error(f"{path}: not a text YAML file (undecodable byte at offset {e.start})") from None
    except yaml.YAMLError as e:
        raise error(f"{path}: not valid YAML ({str(e).splitlines()[0]})") from None
    if mapping:
        doc = {} if doc is None else doc
        if not isinstance(doc, dict):
            raise error(f"{path}: expected a mapping of fields, got {type(doc).__name__}")
    return doc


def _load_yaml(path: Path) -> Any:
    return load_yaml(path)


def read_calibration(path: str | os.PathLike, frame_size: tuple[int, int] | None = None) -> dict[str, PinholeCamera]:
    """Read ``calibration.yaml``; check each device and, for the camera, the frame size (W, H)."""
    path = Path(path)
    data = _load_yaml(path)
    if not isinstance(data, dict) or "camera" not in data:
        raise FootageError(f"{path}: field 'camera' is missing")
    cams: dict[str, PinholeCamera] = {}
    for name, d in data.items():
        if name not in DEVICES and not (isinstance(d, dict) and "K" in d):
            continue  # scalar provenance (rms_px, n_views, ...) beside the devices
        if not isinstance(d, dict):
            raise FootageError(f"{path}: field '{name}' must be a mapping")
        try:
            cams[name] = PinholeCamera.from_dict(d, where=f"{path}: {name}")
        except CameraError as e:
            raise FootageError(str(e)) from e
    if frame_size is not None:
        c = cams["camera"]
        if (c.width, c.height) != tuple(frame_size):
            raise FootageError(
                f"{path}: camera image size {c.width}x{c.height} does not match the frames ({frame_size[0]}x{frame_size[1]})"
            )
    return cams


def read_meta(path: str | os.PathLike, required: tuple[str, ...] = ()) -> dict[str, Any]:
    """Read ``meta.yaml`` and check that the fields a stage needs are present."""
    path = Path(path)
    meta = _load_yaml(path) or {}
    if not isinstance(meta, dict):
        raise FootageError(f"{path}: must be a mapping of known inputs")
    missing = [k for k in required if k not in meta]
    if missing:
        raise FootageError(f"{path}: missing field(s) {missing}")
    return meta


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read one image file as RGB uint8 (H, W, 3); a clear error if missing or corrupt."""
    path = Path(path)
    if not path.is_file():
        raise FootageError(f"{path}: image file is missing")
    if path.suffix.lower() in (".jpg", ".jpeg"):
        # OpenCV decodes a truncated JPEG with only a libjpeg warning (grey rows at the bottom)
        with open(path, "rb") as fh:
            fh.seek(max(0, path.stat().st_size - 2048))
            if b"\xff\xd9" not in fh.read():
                raise FootageError(f"{path}: truncated JPEG (no end-of-image marker)")
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise FootageError(f"{path}: not a readable image (corrupt or unsupported format)")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


#: header names ``times.csv`` may give its time column (seconds) when it has several columns
TIME_COLUMNS = frozenset({"time_s", "time", "t", "timestamp_s", "seconds"})


def _natural_key(p: Path) -> list:
    """Sort key that orders numbers by value: frame2.png before frame10.png (unpadded names, as
    ffmpeg's %d writes them, sort as text 0, 1, 10, 11, 2, ...)."""
    return [int(c) if c.isdigit() else c for c in re.split(r"(\d+)", p.name)]


def read_times(path: str | os.PathLike, n: int, prefix: bool = False) -> np.ndarray:
    """Read ``times.csv`` (header line, one time per frame, seconds) and check monotonicity.

    ``prefix``: the frames are the first ``n`` of a longer clip (a ``max_frames`` read): the file
    must hold at least ``n`` times, and the first ``n`` are returned."""
    path = Path(path)
    if not path.is_file():
        raise FootageError(f"{path}: file is missing")
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise FootageError(f"{path}: not a text file (expected a header line and one time per line)") from None
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise FootageError(f"{path}: empty (expected a header line such as 'time_s', then one time per frame)")
    header = [h.strip().lower() for h in lines[0].split(",")]
    try:
        float(header[0])
    except ValueError:
        pass
    else:
        raise FootageError(f"{path}: the first line {lines[0]!r} is a number, not a header: expected a header line "
                           f"such as 'time_s' (the first time would be dropped)")
    if len(header) == 1:
        col = 0
    else:
        named = [i for i, h in enumerate(header) if h in TIME_COLUMNS]
        if len(named) != 1:
            raise FootageError(f"{path}: {len(header)} columns {header} and {'none' if not named else 'several'} named "
                               f"as the time in seconds (expected one of {sorted(TIME_COLUMNS)})")
        col = named[0]
    rows = [ln.split(",") for ln in lines[1:]]
    for k, r in enumerate(rows):
        if len(r) != len(header):
            raise FootageError(f"{path}: line {k + 2} has {len(r)} fields but the header {lines[0]!r} has "
                               f"{len(header)} (a decimal comma? times are written with a decimal point)")
    try:
        t = np.array([float(r[col]) for r in rows])
    except ValueError as e:
        raise FootageError(f"{path}: non-numeric time value ({e})") from e
    if prefix and t.size >= n:
        t = t[:n]
    return check_times(t, n, str(path))


def check_times(t: np.ndarray, n: int, where: str) -> np.ndarray:
    """Validate frame times: one per frame, finite, strictly increasing."""
    t = np.asarray(t, dtype=float)
    if t.shape != (n,):
        raise FootageError(f"{where}: {t.size} timestamps for {n} frames")
    if not np.all(np.isfinite(t)):
        raise FootageError(f"{where}: timestamps contain NaN or inf")
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if bad.size:
        i = int(bad[0])
        raise FootageError(f"{where}: timestamps must increase, but frame {i + 1} ({t[i + 1]:.6f} s) is not after frame {i} ({t[i]:.6f} s)")
    return t


def read_video(path: str | os.PathLike, max_frames: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Decode a video file with PyAV; return RGB frames (T,H,W,3) and the container's timestamps (s).

    Timestamps are each frame's presentation time relative to the first, so a variable frame
    rate (webcams) is kept rather than assumed constant.
    """
    import av  # local import: only needed for video input

    path = Path(path)
    if not path.is_file():
        raise FootageError(f"{path}: video file is missing")
    import av.logging

    frames, times = [], []
    declared = None
    old_level, old_skip = av.logging.get_level(), av.logging.get_skip_repeated()
    av.logging.set_level(av.logging.ERROR)
    av.logging.set_skip_repeated(False)  # the same warning for a second file must still be seen
    try:
        with av.logging.Capture() as ff_log, av.open(str(path)) as container:
            if not container.streams.video:
                raise FootageError(f"{path}: contains no video stream")
            stream = container.streams.video[0]
            if container.duration:
                declared = container.duration / 1e6  # microseconds
            for frame in container.decode(stream):
                if frame.pts is None:
                    raise FootageError(f"{path}: frame {len(frames)} has no timestamp")
                times.append(float(frame.pts * stream.time_base))
                frames.append(frame.to_ndarray(format="rgb24"))
                if max_frames is not None and len(frames) >= max_frames:
                    break
    except av.error.FFmpegError as e:  # type: ignore[attr-defined]
        raise FootageError(f"{path}: cannot decode video after {len(frames)} frames ({e})") from e
    finally:
        av.logging.set_level(old_level)
        av.logging.set_skip_repeated(old_skip)
    errors = [msg.strip() for level, _, msg in ff_log if level <= av.logging.ERROR]
    if frames and any("ended prematurely" in m or "truncat" in m.lower() for m in errors):
        raise FootageError(f"{path}: video is truncated after {len(frames)} frames (decoder: {errors[0]})")
    if not frames:
        raise FootageError(f"{path}: video has zero frames")
    shapes = {f.shape for f in frames}
    if len(shapes) > 1:
        raise FootageError(f"{path}: frames have different sizes {sorted(shapes)}")
    t = np.asarray(times)
    if max_frames is None and declared is not None and len(t) > 1:
        dt = float(np.median(np.diff(t)))
        if t[-1] + dt < declared - 2 * dt:
            raise FootageError(
                f"{path}: video is truncated: the container declares {declared:.3f} s but frames end at {t[-1] + dt:.3f} s"
            )
    t = t - t[0]
    return np.stack(frames), check_times(t, len(frames), str(path))


def read_footage(folder: str | os.PathLike, required_meta: tuple[str, ...] = (), max_frames: int | None = None) -> Footage:
    """Read and validate a footage folder (see the module docstring for the layout).

    Raises:
        FootageError: naming the file and field for anything missing or malformed.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FootageError(f"{folder}: footage folder is missing")
    videos = [p for p in sorted(folder.iterdir()) if p.suffix.lower() in VIDEO_EXTS and not p.name.startswith(".")]
    if len(videos) > 1:
        named = [p for p in videos if p.stem == "video"]
        if len(named) != 1:
            raise FootageError(f"{folder}: several video files ({', '.join(p.name for p in videos)}); keep one, or name "
                               f"the one to read video.<ext>")
        videos = named
    fdir = folder / FRAME_DIR
    if fdir.is_dir():
        files = sorted((p for p in fdir.iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")),
                       key=_natural_key)
        if not files:
            raise FootageError(f"{fdir}: contains zero frames")
        times = read_times(folder / "times.csv", len(files))
        if max_frames is not None:
            files, times = files[:max_frames], times[:max_frames]
        imgs = [read_image(p) for p in files]
        shape0 = imgs[0].shape
        for p, im in zip(files, imgs):
            if im.shape != shape0:
                raise FootageError(f"{p}: frame size {im.shape[1]}x{im.shape[0]} differs from {files[0].name} ({shape0[1]}x{shape0[0]})")
        frames = np.stack(imgs)
    elif videos:
        frames, times = read_video(videos[0], max_frames=max_frames)
        if (folder / "times.csv").is_file():
            times = read_times(folder / "times.csv", frames.shape[0], prefix=max_frames is not None)
    else:
        raise FootageError(f"{folder}: no '{FRAME_DIR}/' folder and no video file ({', '.join(VIDEO_EXTS)})")
    cams = read_calibration(folder / "calibration.yaml", frame_size=(frames.shape[2], frames.shape[1]))
    meta = read_meta(folder / "meta.yaml", required=required_meta)
    n_meta = meta.get("n_frames")
    if n_meta is not None and (isinstance(n_meta, bool) or not isinstance(n_meta, int)):
        raise FootageError(f"{folder / 'meta.yaml'}: field 'n_frames' = {n_meta!r}: expected a whole number of frames")
    if n_meta is not None and max_frames is None and n_meta != frames.shape[0]:
        raise FootageError(f"{folder / 'meta.yaml'}: field 'n_frames' = {n_meta!r} but the folder holds "
                           f"{frames.shape[0]} frames")
    for key in ("fps", "fps_nominal"):
        if key in meta:
            v = meta[key]
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) and v > 0
            if not ok:
                raise FootageError(f"{folder / 'meta.yaml'}: field '{key}' = {v!r} is not valid: expected a frame "
                                   "rate > 0 (frames per second)")
    return Footage(frames=frames, times=times, cameras=cams, meta=meta, path=folder)


def read_truth(folder: str | os.PathLike) -> dict[str, Any]:
    """Read the truth beside a synthetic footage folder. ONLY scoring stages may call this."""
    return _load_yaml(truth_path(folder))
