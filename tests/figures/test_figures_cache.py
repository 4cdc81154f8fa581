"""The reference cache: keys from the scene's content, hits and misses, incomplete entries rendered again."""

import shutil

import numpy as np

from convsss.figures.cache import ReferenceCache, canonical, reference_key
from convsss.figures.scenes import SceneSpec, mesh_path, scene_dict


def test_key_follows_the_content_not_the_path(tmp_path):
    moved = tmp_path / "bunny.obj"
    shutil.copyfile(mesh_path("bunny"), moved)
    a = {"type": "obj", "filename": str(mesh_path("bunny"))}
    b = {"type": "obj", "filename": str(moved)}
    assert reference_key("exact", a, spp=2) == reference_key("exact", b, spp=2)
    assert reference_key("exact", a, spp=2) != reference_key("exact", a, spp=4)
    assert reference_key("exact", a, spp=2) != reference_key("volpathmis", a, spp=2)


def test_key_of_a_scene_dictionary_is_stable_and_sees_every_change():
    spec = SceneSpec("bunny", "wholemilk", 40.0)
    key = reference_key("exact", scene_dict(spec, 64, 64), resolution=64)
    assert key == reference_key("exact", scene_dict(spec, 64, 64), resolution=64)
    for other in (SceneSpec("bunny", "wholemilk", 4.0), SceneSpec("bunny", "marble", 40.0),
                  SceneSpec("bunny", "wholemilk", 40.0, turn_deg=180.0)):
        assert reference_key("exact", scene_dict(other, 64, 64), resolution=64) != key
    assert canonical({"b": 1.0, "a": [np.float32(0.5), (1, 2)]}) == {"a": [0.5, [1, 2]], "b": 1.0}


def test_cache_renders_once_then_reads_back(tmp_path):
    cache = ReferenceCache(tmp_path / "cache")
    calls = []

    def render():
        calls.append(1)
        return np.full((4, 5, 3), 0.25), {"note": "made"}

    scene = {"type": "scene", "value": 1.0}
    first, meta, hit = cache.get("exact", scene, {"spp": 1}, render, "a test")
    assert not hit and meta["note"] == "made" and meta["seconds"] >= 0
    second, meta2, hit2 = cache.get("exact", scene, {"spp": 1}, render, "a test")
    assert hit2 and len(calls) == 1 and np.array_equal(first, second) and meta2["key"] == meta["key"]
    assert (cache.hits, cache.misses) == (1, 1)
    # an entry without its JSON is incomplete: rendered again
    exr, meta_path = cache.paths("exact", meta["key"])
    meta_path.unlink()
    cache.get("exact", scene, {"spp": 1}, render)
    assert len(calls) == 2 and exr.is_file() and meta_path.is_file()
