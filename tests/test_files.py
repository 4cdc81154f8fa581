import json
import math
import os
import stat

import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.files import atomic_write, check_outputs, json_ready, write_files, write_text


def _fail(tmp):
    """A write that dies half way."""
    open(tmp, "w").write("half")
    raise RuntimeError("disk full")


def test_write_text_is_whole_and_leaves_no_temporary(tmp_path):
    path = write_text(tmp_path / "sub" / "a.json", "{}")
    assert path.read_text() == "{}" and [p.name for p in path.parent.iterdir()] == ["a.json"]


def test_failed_write_keeps_the_old_file_and_leaves_nothing(tmp_path):
    path = write_text(tmp_path / "a.txt", "old")

    with pytest.raises(RuntimeError):
        atomic_write(path, _fail)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_json_ready():
    value = {"a": np.arange(3), 1: (np.int64(2), np.float32(0.5)), "b": [math.inf, np.nan, 1.0]}
    assert json.loads(json.dumps(json_ready(value))) == {"a": [0, 1, 2], "1": [2, 0.5], "b": [None, None, 1.0]}


def test_written_files_get_ordinary_permissions(tmp_path):
    mask = os.umask(0o022)
    try:
        path = write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(mask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644


def _writer(text):
    return lambda tmp: open(tmp, "w").write(text)


def test_write_files_lands_all_files_together(tmp_path):
    paths = write_files({tmp_path / "a.exr": _writer("a"), tmp_path / "sub" / "b.json": _writer("b")})
    assert [p.read_text() for p in paths] == ["a", "b"]
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["a.exr", "b.json", "sub"]


def test_write_files_writes_nothing_when_one_file_fails(tmp_path):
    old = write_text(tmp_path / "a.exr", "old")

    with pytest.raises(RuntimeError):
        write_files({old: _writer("new"), tmp_path / "b.png": _fail, tmp_path / "c.json": _writer("c")})
    assert old.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["a.exr"]


def test_write_files_refuses_a_folder_before_writing_anything(tmp_path):
    (tmp_path / "out.png").mkdir()
    with pytest.raises(ConvsssError, match="'.*out.png' is a folder"):
        write_files({tmp_path / "out.exr": _writer("a"), tmp_path / "out.png": _writer("b")})
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"] and not any((tmp_path / "out.png").iterdir())


def test_write_files_reports_an_unwritable_target_in_one_line(tmp_path):
    (tmp_path / "file.xml").write_text("x")
    with pytest.raises(ConvsssError, match="cannot write"):
        write_files({tmp_path / "a.exr": _writer("a"), tmp_path / "file.xml" / "b.png": _writer("b")})
    assert [p.name for p in tmp_path.iterdir()] == ["file.xml"]


def test_check_outputs_refuses_an_input_under_any_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "scene.xml"
    scene.write_text("<scene/>")
    (tmp_path / "link.xml").symlink_to(scene)
    os.link(scene, tmp_path / "hard.xml")
    for output in ("scene.xml", "./sub/../scene.xml", str(scene), "link.xml", "hard.xml"):
        with pytest.raises(ConvsssError, match="is an input of this command"):
            check_outputs(["out.png", output], inputs=[scene])
    check_outputs(["out.png", "scene.json"], inputs=[scene, "missing.exr"])


def test_check_outputs_refuses_unwritable_places(tmp_path):
    (tmp_path / "file.xml").write_text("x")
    (tmp_path / "out.png").mkdir()
    cases = {"/proc/x/img.exr": "cannot write into '/proc/x'", str(tmp_path / "file.xml" / "img.exr"): "not a folder",
             str(tmp_path / "out.png"): "is a folder"}
    for output, message in cases.items():
        with pytest.raises(ConvsssError, match=message):
            check_outputs([output])
    with pytest.raises(ConvsssError, match="named twice"):
        check_outputs([tmp_path / "a.png", tmp_path / "a.png"])
    check_outputs([tmp_path / "new" / "folders" / "img.exr"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.xml", "out.png"]


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_check_outputs_refuses_a_read_only_folder(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir(mode=0o555)
    with pytest.raises(ConvsssError, match="cannot write into"):
        check_outputs([folder / "img.exr"])


def test_a_failed_mitsuba_write_is_one_line_and_leaves_nothing(tmp_path):
    """Mitsuba's streams report a full disk as a RuntimeError (issue 30, defect 10): one line, no file left."""
    def full(tmp):
        raise RuntimeError(f'[FileStream] "{tmp}": I/O error while attempting to write 98304 bytes: No space left on '
                           'device')  # what Mitsuba 3.9 raised on a full tmpfs

    with pytest.raises(ConvsssError, match=r"cannot write .*a\.exr': No space left on device$"):
        write_files({tmp_path / "a.exr": full})
    assert list(tmp_path.iterdir()) == []


def test_temporaries_of_a_killed_run_are_removed_by_the_next(tmp_path):
    """A run killed while writing (SIGKILL: no cleanup) leaves ``.STEM.PID.XXXXXXXX.SUFFIX``; the next write of the
    same file removes those of processes that no longer run, and keeps a running one's and other files."""
    import subprocess

    dead = subprocess.Popen(["true"])
    dead.wait()
    stale = tmp_path / f".img.{dead.pid}.abcd_123.exr"
    live = tmp_path / f".img.{os.getpid()}.zzzzzzzz.exr"
    other = tmp_path / f".other.{dead.pid}.abcd_123.exr"
    for path in (stale, live, other):
        path.write_bytes(b"partial")
    write_text(tmp_path / "img.exr", "whole")
    assert not stale.exists() and live.exists() and other.exists()
    assert (tmp_path / "img.exr").read_text() == "whole"
