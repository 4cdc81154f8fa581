"""The renderer's tiny scenes (``tests/scene/conftest.py``) for the editor's tests, and a running editor server."""

import importlib.util
import threading
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location("_scene_fixtures", Path(__file__).parents[1] / "scene" / "conftest.py")
_scene_fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_scene_fixtures)
mi, sphere_scene = _scene_fixtures.mi, _scene_fixtures.sphere_scene


@pytest.fixture
def session(mi, sphere_scene):
    """``session(render=None, **scene_options)`` -> an EditSession of a 32x32, 1 spp sphere scene (``render``: render
    parameters instead of the defaults)."""
    from convsss.editor import EditSession
    from convsss.scene.integrator import register, scene_parameters
    from convsss.scene.loading import load_scene
    from convsss.scene.params import RenderParams

    def make(render=None, **options):
        register()
        scene = load_scene(sphere_scene(**{"res": 32, "spp": 1, **options}))
        params = None
        if render is not None:
            params = RenderParams(**{**(scene_parameters(scene) or {}), **render})
        return EditSession(scene, params=params)

    return make


@pytest.fixture
def editor_server(session):
    """A running :class:`EditorServer` on a free port of 127.0.0.1 (a dielectric sphere), shut down after the test."""
    from convsss.editor.server import EditorServer

    server = EditorServer(session(boundary="dielectric"), "127.0.0.1", 0)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server
    server.shutdown()
    server.server_close()
    thread.join(10)
