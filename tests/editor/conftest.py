"""An edit session of the renderer's tiny scenes (``tests/conftest.py``), and a running editor server."""

import threading

import pytest


@pytest.fixture
def session(mi, sphere_scene):
    """``session(render=None, **scene_options)`` -> an EditSession of a 32x32, 1 spp sphere scene rendered by the
    transport (walk_depth 0: these tests edit the transport's stages; ``render``: render parameters instead)."""
    from convsss.editor import EditSession
    from convsss.pipeline.integrator import register, scene_parameters
    from convsss.pipeline.params import RenderParams
    from convsss.scene.loading import load_scene

    def make(render=None, **options):
        register()
        scene = load_scene(sphere_scene(**{"res": 32, "spp": 1, **options}))
        params = RenderParams(**{**(scene_parameters(scene) or {}), "walk_depth": 0.0, **(render or {})})
        return EditSession(scene, params=params)

    return make


@pytest.fixture
def render_loop(session):
    """``render_loop(max_spp=4, **scene_options)`` -> a :class:`RenderLoop` running in a thread of its own, which made
    its session (a dielectric sphere by default) as the editor's command does; stopped after the test."""
    from convsss.editor.loop import RenderLoop

    started = []

    def make(max_spp=4, **options):
        made, ready = {}, threading.Event()

        def render():
            try:
                made["loop"] = RenderLoop(session(**{"boundary": "dielectric", **options}), max_spp)
            finally:
                ready.set()
            made["loop"].run()

        thread = threading.Thread(target=render, daemon=True)
        thread.start()
        ready.wait(300)
        started.append((made["loop"], thread))
        return made["loop"]

    yield make
    for loop, thread in started:
        loop.stop()
        thread.join(60)


@pytest.fixture
def editor_server(render_loop):
    """A running :class:`EditorServer` on a free port of 127.0.0.1 (a dielectric sphere, refined to 4 spp), shut down
    after the test."""
    from convsss.editor.server import EditorServer

    server = EditorServer(render_loop(), "127.0.0.1", 0)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server
    server.shutdown()
    server.server_close()
    thread.join(10)
