"""Progress lines: counts and the time left, and no negative time left when a total was an estimate."""

from __future__ import annotations

from vidsim.log.progress import Progress


def test_progress_lines_count_and_never_promise_negative_time(capsys):
    p = Progress(2, "steps", every_s=0.0)
    p.update(note="a")
    p.update(note="b")
    p.update(note="c")  # one more step than estimated (a diagnosis's optional pair step)
    lines = capsys.readouterr().err.splitlines()
    assert [ln.split("]")[0] for ln in lines] == ["[steps"] * 3
    assert " 1/2 " in lines[0] and "s left" in lines[0] and lines[0].endswith("a")
    assert " 2/2 " in lines[1] and "~   0.0s left" in lines[1]
    assert "3 (over the 2 estimated)" in lines[2] and "left" not in lines[2] and lines[2].endswith("c")


def test_disabled_progress_prints_nothing(capsys):
    p = Progress(3, "steps", every_s=0.0, enabled=False)
    for _ in range(4):
        p.update()
    assert capsys.readouterr().err == ""
