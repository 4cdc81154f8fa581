"""A scene rendered to files (convsss.outputs): the library functions the CLI and batch's workers call."""

import json

import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.image import read_image
from convsss.outputs import pick_sensor, reference_to_files, render_to_files
from convsss.scene.source import SceneSource

SOURCE = SceneSource(mesh="bunny", material="marble", size_mm=20.0, width=16, height=16)


def test_render_to_files_writes_the_files_its_stats_name_and_the_same_seed_the_same_image(tmp_path):
    heard = []
    stats = render_to_files(SOURCE, tmp_path / "a", spp=1, mask=True, stats_path=tmp_path / "a.json",
                            progress=heard.append)
    assert set(stats["outputs"]) == {"exr", "png", "mask", "stats"}
    assert all((tmp_path / name).is_file() for name in ("a.exr", "a.png", "a-mask.png", "a.json"))
    assert json.loads((tmp_path / "a.json").read_text())["seconds"]["total"] > 0
    assert heard[0] == "scene_load" and heard[-1] == "write"
    render_to_files(SOURCE, tmp_path / "b", spp=1, mask=True)
    assert np.array_equal(read_image(tmp_path / "a.exr"), read_image(tmp_path / "b.exr"))
    with pytest.raises(ConvsssError, match="accuracy"):  # refused before anything is loaded or written
        render_to_files(SOURCE, tmp_path / "c", spp=1, accuracy=0.0)
    assert not (tmp_path / "c.exr").exists()


def test_reference_to_files_saves_every_pass_and_says_so(tmp_path):
    heard = []
    source = SceneSource(**{**SOURCE.__dict__, "boundary": "null"})  # the quick scene's point lights reach it
    record = reference_to_files(source, tmp_path / "r", spp=2, pass_spp=1, progress=lambda *a: heard.append(a))
    assert record["spp_done"] == 2 and record["passes_done"] == 2
    assert [h[0] for h in heard] == [0, 1, 2]
    assert json.loads((tmp_path / "r.json").read_text())["spp_done"] == 2


def test_pick_sensor_refuses_a_sensor_the_scene_lacks():
    scene = SOURCE.load()
    assert pick_sensor(scene, 0) is scene.sensors()[0]
    with pytest.raises(ConvsssError, match="the scene has 1 sensor"):
        pick_sensor(scene, 1)
