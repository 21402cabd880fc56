"""Footage folder format: round trip, and clear errors for bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from vidsim.errors import FootageError
from vidsim.io.footage import read_footage, read_truth, read_video, truth_path, write_footage, write_truth
from vidsim.video.camera import PinholeCamera, intrinsics


def _cam(w=64, h=48):
    return PinholeCamera(intrinsics(60.0, None, (w - 1) / 2, (h - 1) / 2), width=w, height=h)


def _write(folder: Path, rng, n=5, w=64, h=48):
    frames = rng.integers(0, 255, (n, h, w, 3), dtype=np.uint8)
    times = np.arange(n) / 30.0
    write_footage(folder, frames, times, {"camera": _cam(w, h)}, {"object": "box"})
    return frames, times


def test_round_trip(tmp_path, rng):
    frames, times = _write(tmp_path / "f", rng)
    fo = read_footage(tmp_path / "f", required_meta=("object",))
    assert np.array_equal(fo.frames, frames)  # PNG is lossless
    assert np.allclose(fo.times, times)
    assert np.allclose(fo.camera.K, _cam().K)
    write_truth(tmp_path / "f", {"secret": 1})
    assert truth_path(tmp_path / "f").parent == tmp_path  # truth is beside, never inside
    assert not any("truth" in p.name for p in (tmp_path / "f").rglob("*"))
    assert read_truth(tmp_path / "f")["secret"] == 1


def test_missing_folder(tmp_path):
    with pytest.raises(FootageError, match="footage folder is missing"):
        read_footage(tmp_path / "absent")


def test_corrupt_image_is_named(tmp_path, rng):
    _write(tmp_path / "f", rng)
    bad = tmp_path / "f" / "frames" / "000002.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    with pytest.raises(FootageError, match="000002.png.*corrupt"):
        read_footage(tmp_path / "f")


def test_frames_of_different_sizes(tmp_path, rng):
    import cv2

    _write(tmp_path / "f", rng)
    cv2.imwrite(str(tmp_path / "f" / "frames" / "000003.png"), np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(FootageError, match="000003.png.*differs"):
        read_footage(tmp_path / "f")


def test_backwards_timestamps(tmp_path, rng):
    _write(tmp_path / "f", rng)
    (tmp_path / "f" / "times.csv").write_text("time_s\n0\n0.1\n0.05\n0.2\n0.3\n")
    with pytest.raises(FootageError, match="times.csv.*must increase.*frame 2"):
        read_footage(tmp_path / "f")


def test_missing_meta_field(tmp_path, rng):
    _write(tmp_path / "f", rng)
    with pytest.raises(FootageError, match=r"meta.yaml.*missing field.*inertia"):
        read_footage(tmp_path / "f", required_meta=("inertia",))


def test_singular_camera_matrix(tmp_path, rng):
    _write(tmp_path / "f", rng)
    p = tmp_path / "f" / "calibration.yaml"
    d = yaml.safe_load(p.read_text())
    d["camera"]["K"] = [[0, 0, 0], [0, 0, 0], [0, 0, 1]]
    p.write_text(yaml.safe_dump(d))
    with pytest.raises(FootageError, match="calibration.yaml.*'K'.*singular"):
        read_footage(tmp_path / "f")


def test_calibration_frame_size_mismatch(tmp_path, rng):
    _write(tmp_path / "f", rng)
    p = tmp_path / "f" / "calibration.yaml"
    d = yaml.safe_load(p.read_text())
    d["camera"]["width"] = 640
    p.write_text(yaml.safe_dump(d))
    with pytest.raises(FootageError, match="640x48 does not match the frames"):
        read_footage(tmp_path / "f")


def test_zero_frames(tmp_path, rng):
    _write(tmp_path / "f", rng)
    for p in (tmp_path / "f" / "frames").iterdir():
        p.unlink()
    with pytest.raises(FootageError, match="zero frames"):
        read_footage(tmp_path / "f")


@pytest.mark.parametrize("keep,message", [(2000, "zero frames"), (100_000, "truncated"), (0.5, "truncated")])
def test_truncated_video(tmp_path, shared_data, keep, message):
    data = (shared_data / "tracklab_physics" / "verticalToss.webm").read_bytes()
    n = int(keep * len(data)) if isinstance(keep, float) else keep
    bad = tmp_path / "cut.webm"
    bad.write_bytes(data[:n])
    with pytest.raises(FootageError, match=f"cut.webm.*{message}"):
        read_video(bad)


def test_real_webm_uses_container_timestamps(shared_data):
    frames, t = read_video(shared_data / "tracklab_physics" / "verticalToss.webm")
    assert frames.shape[1:] == (480, 640, 3)
    assert frames.shape[0] == 76
    dt = np.diff(t)
    assert np.all(dt > 0)
    # variable frame rate near 31 fps: not a constant 1/30 s
    assert 1 / 40 < np.median(dt) < 1 / 25
    assert dt.max() - dt.min() > 1e-3


def test_a_finished_folder_replaces_the_old_one_and_its_stale_truth(tmp_path):
    """replace_dir: the new folder lands under the output's name, the old one and the files that
    belonged with it (its truth beside it) are gone, and nothing is left aside."""
    from vidsim.io.atomic import replace_dir

    out, tmp = tmp_path / "clip", tmp_path / ".clip.part"
    out.mkdir()
    (out / "old.txt").write_text("old")
    write_truth(out, {"old": True})
    tmp.mkdir()
    (tmp / "new.txt").write_text("new")
    replace_dir(tmp, out, stale=(truth_path(out),))
    assert sorted(p.name for p in out.iterdir()) == ["new.txt"]
    assert not truth_path(out).exists()  # the caller writes the new truth after the swap
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip"]
    # and into an empty place
    tmp.mkdir()
    replace_dir(tmp, tmp_path / "fresh")
    assert (tmp_path / "fresh").is_dir() and not tmp.exists()


def test_video_with_times_csv_read_in_part(tmp_path):
    """max_frames on a video folder with its own times.csv: the first times go with the first frames
    (was '10 timestamps for 5 frames'); a times.csv of binary bytes is named, not a UnicodeDecodeError."""
    from vidsim.io.video import write_animation

    folder = tmp_path / "v"
    folder.mkdir()
    frames = np.zeros((10, 48, 64, 3), np.uint8)
    frames[:, 10:20, 10:20] = 200
    write_animation(folder / "clip.mp4", frames, 30.0)
    times = np.arange(10) / 25.0 + 0.5
    (folder / "times.csv").write_text("t\n" + "".join(f"{t}\n" for t in times))
    (folder / "calibration.yaml").write_text(yaml.safe_dump({"camera": _cam().to_dict()}))
    (folder / "meta.yaml").write_text(yaml.safe_dump({"object": "box"}))
    fo = read_footage(folder, max_frames=5)
    assert fo.frames.shape[0] == 5 and np.allclose(fo.times, times[:5])
    assert read_footage(folder).frames.shape[0] == 10
    (folder / "times.csv").write_bytes(bytes(range(128, 256)) * 4)
    with pytest.raises(FootageError, match="times.csv: not a text file"):
        read_footage(folder)


@pytest.mark.parametrize("field,value,message", [
    ("width", "abc", "field 'width' must be a whole number"),
    ("t", "abc", "field 't' is not numeric"),
    ("dist", [0.1, 0, 0, 0, 0, 0.2, 0, 0], "only OpenCV's five-coefficient model"),
])
def test_calibration_fields_of_the_wrong_kind_are_named(tmp_path, rng, field, value, message):
    _write(tmp_path / "f", rng)
    p = tmp_path / "f" / "calibration.yaml"
    d = yaml.safe_load(p.read_text())
    d["camera"][field] = value
    p.write_text(yaml.safe_dump(d))
    with pytest.raises(FootageError, match=f"calibration.yaml.*{message}"):
        read_footage(tmp_path / "f")


def test_write_animation_refuses_frames_it_would_spoil(tmp_path):
    from vidsim.io.video import write_animation

    with pytest.raises(ValueError, match="must be uint8, got float64"):
        write_animation(tmp_path / "a.mp4", np.ones((3, 8, 8, 3)), 30.0)
    with pytest.raises(ValueError, match=r"\(T, H, W, 3\)"):
        write_animation(tmp_path / "a.gif", np.zeros((8, 8, 3), np.uint8), 30.0)
    assert not list(tmp_path.iterdir())


def test_times_csv_header_and_columns(tmp_path, rng):
    """times.csv is read by its header: a 'frame,time_s' file was read as frame numbers in seconds
    (30x too slow, no error); a header-less file silently lost its first time; a decimal comma gave a
    misleading 'must increase'."""
    frames, times = _write(tmp_path / "f", rng)
    csv = tmp_path / "f" / "times.csv"
    csv.write_text("frame,time_s\n" + "".join(f"{i},{t:.6f}\n" for i, t in enumerate(times)))
    assert np.allclose(read_footage(tmp_path / "f").times, times, atol=1e-6)
    for text, match in (("".join(f"{t:.6f}\n" for t in times), "is a number, not a header"),
                        ("frame,index\n" + "".join(f"{i},{i}\n" for i in range(5)), "none named as the time"),
                        ("time_s\n" + "".join(f"{t:.6f}".replace(".", ",") + "\n" for t in times), "decimal comma"),
                        ("", "empty")):
        csv.write_text(text)
        with pytest.raises(FootageError, match=match):
            read_footage(tmp_path / "f")


def test_unpadded_frame_names_are_read_in_numeric_order(tmp_path, rng):
    """frame0.png ... frame11.png (ffmpeg's %d) sorted as text gave 0, 1, 10, 11, 2, ... silently."""
    import cv2

    frames, times = _write(tmp_path / "f", rng, n=12)
    fdir = tmp_path / "f" / "frames"
    for p in sorted(fdir.iterdir()):
        p.unlink()
    for i, im in enumerate(frames):
        cv2.imwrite(str(fdir / f"frame{i}.png"), cv2.cvtColor(im, cv2.COLOR_RGB2BGR))
    assert np.array_equal(read_footage(tmp_path / "f").frames, frames)


def test_several_video_files_are_refused_unless_one_is_named_video(tmp_path, shared_data):
    """With a leftover second video the alphabetically first one was read silently."""
    import shutil

    src = shared_data / "tracklab_physics" / "verticalToss.webm"
    if not src.is_file():
        pytest.skip("shared recording missing")
    folder = tmp_path / "v"
    folder.mkdir()
    shutil.copy(src, folder / "toss.webm")
    shutil.copy(src, folder / "a_backup.webm")
    with pytest.raises(FootageError, match="several video files.*a_backup.webm, toss.webm.*video.<ext>"):
        read_footage(folder, max_frames=2)
    (folder / "toss.webm").rename(folder / "video.webm")
    # the chosen file is video.webm: the reader goes on to the calibration (missing here)
    with pytest.raises(FootageError, match="calibration.yaml"):
        read_footage(folder, max_frames=2)
