"""Rerun recordings behind a small interface, plus a no-op logger for tests.

Entity layout (the same in every stage, so recordings can be compared side by side)::

    footage/camera/image      the input frames            sim/camera/image     simulated frames
    footage/camera/mask       input silhouettes           sim/camera/mask      simulated silhouettes
    world/...                 3D content (meshes, trajectories, cameras)
    metric/<name>             per-frame metric values     optim/<name>         per-iteration values

Time lines: ``frame`` (sequence index of the footage) and ``iter`` (optimiser iteration).
The ``.rrd`` is written to a temporary file and renamed onto its path on :meth:`close`, so a
killed stage never leaves a truncated recording that Snakemake would take as done.
Open one with ``rerun results/<stage>/<name>.rrd``.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any, Protocol

import numpy as np


class Logger(Protocol):
    """What stages log through; implemented by :class:`RerunLogger` and :class:`NullLogger`."""

    def set_frame(self, i: int) -> None: ...
    def image(self, entity: str, img: np.ndarray) -> None: ...
    def mask(self, entity: str, mask: np.ndarray) -> None: ...
    def scalar(self, entity: str, value: float) -> None: ...
    def series(self, entity: str, values: np.ndarray, timeline: str = "iter") -> None: ...
    def points3d(self, entity: str, pts: np.ndarray, radii: float = 0.005, colors: Any = None) -> None: ...
    def mesh3d(self, entity: str, vertices: np.ndarray, faces: np.ndarray, color: Any = None) -> None: ...
    def arrows2d(self, entity: str, origins: np.ndarray, vectors: np.ndarray) -> None: ...
    def text(self, entity: str, text: str) -> None: ...
    def close(self) -> None: ...


class NullLogger:
    """Logs nothing (tests, benchmarks)."""

    def __getattr__(self, name: str):
        return lambda *a, **k: None

    def __enter__(self) -> "NullLogger":
        return self

    def __exit__(self, *exc: Any) -> None:
        return None


class RerunLogger:
    """Writes one Rerun recording (``.rrd``) per stage.

    Args:
        path: destination ``.rrd`` (written atomically on :meth:`close`).
        app_id: Rerun application id, e.g. ``vidsim.calibrate``.
        recording_id: stable id (e.g. the stage's output name) so reruns are comparable.
    """

    def __init__(self, path: str | os.PathLike, app_id: str, recording_id: str | None = None) -> None:
        import rerun as rr

        self._rr = rr
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self.path.with_name(f".{self.path.name}.part")
        app_id = re.sub(r"[^a-z0-9_-]", "-", app_id.lower())  # rerun's entry-name rules
        # default id: the output folder's parent, the folder and the file (calibrate.rrd of two sweep
        # points, or rigid.rrd of two throws, shared the id "calibrate"/"rigid", and the viewer merged
        # them into one recording; cloth/fit/satin_exp1 and cloth/fit_cmaes/satin_exp1 shared
        # "satin_exp1/cloth"), with a stage's staging folder (".<name>.part") named as its final one
        def final(name: str) -> str:
            m = re.fullmatch(r"\.(.+)\.part(?:-[^/]*)?", name)
            return m.group(1) if m else name

        rid = "/".join(final(p) for p in (self.path.parent.parent.name, self.path.parent.name) if p) + f"/{self.path.stem}"
        self.rec = rr.RecordingStream(app_id, recording_id=recording_id or rid)
        self.rec.save(str(self._tmp))
        self._closed = False

    # -- context manager -------------------------------------------------------------
    def __enter__(self) -> "RerunLogger":
        return self

    def __exit__(self, exc_type: Any, *exc: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    # -- logging ----------------------------------------------------------------------
    def set_frame(self, i: int) -> None:
        self.rec.set_time("frame", sequence=int(i))

    def set_iter(self, i: int) -> None:
        self.rec.set_time("iter", sequence=int(i))

    def image(self, entity: str, img: np.ndarray) -> None:
        self.rec.log(entity, self._rr.Image(np.ascontiguousarray(img)))

    def mask(self, entity: str, mask: np.ndarray) -> None:
        self.rec.log(entity, self._rr.SegmentationImage(np.ascontiguousarray(mask, dtype=np.uint8)))

    def depth(self, entity: str, depth: np.ndarray) -> None:
        d = np.where(np.isfinite(depth), depth, 0).astype(np.float32)
        self.rec.log(entity, self._rr.DepthImage(d, meter=1.0))

    def scalar(self, entity: str, value: float) -> None:
        self.rec.log(entity, self._rr.Scalars(float(value)))

    def series(self, entity: str, values: np.ndarray, timeline: str = "iter") -> None:
        values = np.asarray(values, dtype=float)
        rr = self._rr
        self.rec.send_columns(
            entity,
            indexes=[rr.TimeColumn(timeline, sequence=np.arange(values.size))],
            columns=rr.Scalars.columns(scalars=values),
        )

    def points3d(self, entity: str, pts: np.ndarray, radii: float = 0.005, colors: Any = None) -> None:
        self.rec.log(entity, self._rr.Points3D(np.asarray(pts, dtype=np.float32), radii=radii, colors=colors))

    def lines3d(self, entity: str, strips: list[np.ndarray], colors: Any = None) -> None:
        self.rec.log(entity, self._rr.LineStrips3D([np.asarray(s, np.float32) for s in strips], colors=colors))

    def mesh3d(self, entity: str, vertices: np.ndarray, faces: np.ndarray, color: Any = None) -> None:
        kw = {"vertex_colors": None}
        if color is not None:
            kw = {"albedo_factor": color}
        self.rec.log(
            entity,
            self._rr.Mesh3D(vertex_positions=np.asarray(vertices, np.float32), triangle_indices=np.asarray(faces, np.uint32), **kw),
        )

    def arrows2d(self, entity: str, origins: np.ndarray, vectors: np.ndarray) -> None:
        self.rec.log(entity, self._rr.Arrows2D(origins=np.asarray(origins, np.float32), vectors=np.asarray(vectors, np.float32)))

    def camera(self, entity: str, cam: Any) -> None:
        """Log a :class:`~vidsim.video.camera.PinholeCamera` (pose + intrinsics) at ``entity``."""
        rr = self._rr
        self.rec.log(entity, rr.Transform3D(translation=cam.center, mat3x3=cam.R.T))
        self.rec.log(entity, rr.Pinhole(image_from_camera=cam.K, width=cam.width, height=cam.height))

    def text(self, entity: str, text: str) -> None:
        self.rec.log(entity, self._rr.TextLog(text))

    # -- finishing --------------------------------------------------------------------
    def close(self) -> None:
        """Flush and move the recording onto its final path."""
        if self._closed:
            return
        self.rec.flush()
        self.rec.disconnect()
        with open(self._tmp, "rb") as fh:  # on disk before the rename (a power loss must not leave an empty .rrd)
            os.fsync(fh.fileno())
        os.replace(self._tmp, self.path)
        self._closed = True

    def abort(self) -> None:
        """Drop the partial recording (the stage failed)."""
        if self._closed:
            return
        self.rec.disconnect()
        if self._tmp.exists():
            self._tmp.unlink()
        self._closed = True


class _PlaceholderRerunLogger(RerunLogger):
    """Recording switched off (``log.rerun=false``): the declared ``.rrd`` still appears, holding
    one text entry that says so, so the DAG's outputs are the same either way."""

    def __init__(self, path: str | os.PathLike, app_id: str, recording_id: str | None = None) -> None:
        super().__init__(path, app_id, recording_id)
        RerunLogger.text(self, "log", "recording disabled (log.rerun=false)")

    def __getattribute__(self, name: str):
        if name in ("close", "abort", "__enter__", "__exit__") or name.startswith("_") or name in ("rec", "path"):
            return object.__getattribute__(self, name)
        if callable(getattr(RerunLogger, name, None)):
            return lambda *a, **k: None
        return object.__getattribute__(self, name)


def make_logger(path: str | os.PathLike | None, app_id: str, enabled: bool = True,
                recording_id: str | None = None) -> RerunLogger | NullLogger:
    """A :class:`RerunLogger` writing ``path``; with ``enabled=False`` a placeholder recording
    (so declared outputs exist); a :class:`NullLogger` when ``path`` is None. Files written with
    one ``app_id`` and ``recording_id`` are parts of one recording (:func:`merge_recordings`)."""
    if path is None:
        return NullLogger()
    if not enabled:
        return _PlaceholderRerunLogger(path, app_id, recording_id)
    return RerunLogger(path, app_id, recording_id)


def merge_recordings(parts: list[str | os.PathLike], dest: str | os.PathLike) -> None:
    """Merge ``.rrd`` files into ``dest`` (atomically) with the ``rerun rrd merge`` tool that ships
    with rerun-sdk. Parts logged with one application and recording id (``make_logger``'s
    ``recording_id``) become one recording, so a stage that resumes (keeping the parts of its
    finished pieces) still writes the whole recording."""
    import subprocess
    import sys

    dest = Path(dest)
    if not parts:
        raise ValueError(f"{dest}: no recordings to merge")
    for q in parts:
        if not Path(q).is_file():
            raise FileNotFoundError(f"{q}: recording to merge into {dest} is missing")
    tmp = dest.with_name(f".{dest.name}.part")
    cmd = [sys.executable, "-m", "rerun", "rrd", "merge", *map(str, parts), "-o", str(tmp)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0 or not tmp.is_file():
        tmp.unlink(missing_ok=True)
        tail = (r.stderr or r.stdout).strip().splitlines()[-3:]
        raise RuntimeError(f"{dest}: merging {len(parts)} recordings failed ({' | '.join(tail)})")
    with open(tmp, "rb") as fh:  # on disk before the rename, as io.atomic does
        os.fsync(fh.fileno())
    os.replace(tmp, dest)
