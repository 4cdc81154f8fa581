import json
import math
import os
import stat

import numpy as np
import pytest

from convsss.files import atomic_write, json_ready, write_text


def test_write_text_is_whole_and_leaves_no_temporary(tmp_path):
    path = write_text(tmp_path / "sub" / "a.json", "{}")
    assert path.read_text() == "{}" and [p.name for p in path.parent.iterdir()] == ["a.json"]


def test_failed_write_keeps_the_old_file_and_leaves_nothing(tmp_path):
    path = write_text(tmp_path / "a.txt", "old")

    def fail(tmp):
        open(tmp, "w").write("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        atomic_write(path, fail)
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
