"""The editor's render thread (convsss.editor.loop) and the passes it refines the preview with (EditSession.refine)."""

import threading
import time

import numpy as np
import pytest

from convsss.editor.session import Passes
from convsss.errors import ConvsssError


def _wait(condition, seconds=120):
    end = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.02)


def test_passes_average_and_estimate_the_noise():
    rng = np.random.default_rng(1)
    images = rng.normal(1.0, 0.1, (6, 4, 5, 3))
    passes = Passes(images[0])
    assert passes.noise() is None  # one pass: no variance yet
    for image in images[1:]:
        passes.add(image)
    assert passes.count == 6 and np.allclose(passes.mean, images.mean(axis=0))
    expected = np.sqrt(np.mean(images.var(axis=0, ddof=1) / 6)) / np.sqrt(np.mean(images.mean(axis=0) ** 2))
    assert passes.noise() == pytest.approx(expected)


@pytest.mark.slow
def test_refine_adds_a_pass_of_its_own_seed(session):
    from convsss.pipeline.parts import pass_seed

    s = session()
    first = s.image.copy()
    state = s.refine()
    assert state["spp_reached"] == 2 and state["noise"] is not None and state["version"] == 1
    second = np.asarray(s.integrator.render_prepared(spp=1, seed=pass_seed(s.seed, 1)))[..., :3]
    assert not np.array_equal(second, first)  # another seed: other samples
    assert np.allclose(s.image, (first + second) / 2)
    assert s.update(sigma_a=[0.2, 0.2, 0.2])["spp_reached"] == 1  # an edit starts again from one pass


@pytest.mark.slow
def test_the_loop_refines_while_idle_up_to_max_spp(render_loop):
    loop = render_loop(max_spp=3)
    _wait(lambda: loop.state()["spp_reached"] == 3)
    time.sleep(0.5)
    state = loop.state()
    assert state["spp_reached"] == 3 and state["max_spp"] == 3 and state["noise"] > 0  # and no more passes


@pytest.mark.slow
def test_only_the_loops_thread_renders(render_loop, monkeypatch):
    """Issue 62: the editor crashed in Dr.Jit work launched on a request's thread. Edits submitted from other threads
    are rendered on the loop's thread (the one that made the session)."""
    loop = render_loop(max_spp=8)
    integrator = loop.session.integrator
    threads, shade, prepare = [], integrator.render_prepared, integrator.prepare
    monkeypatch.setattr(integrator, "render_prepared",
                        lambda *a, **k: threads.append(threading.get_ident()) or shade(*a, **k))
    monkeypatch.setattr(integrator, "prepare",
                        lambda *a, **k: threads.append(threading.get_ident()) or prepare(*a, **k))
    states = []
    submitters = [threading.Thread(target=lambda v=v: states.append(loop.submit({"sigma_a": [v, v, v]})))
                  for v in (0.2, 0.3)]
    for t in submitters:
        t.start()
    for t in submitters:
        t.join(300)
    assert len(states) == 2 and {s["version"] for s in states} <= {2, 3} and loop.state()["version"] == 3
    assert threads and set(threads) == {loop.thread_id}
    assert loop.thread_id not in {t.ident for t in submitters} | {threading.get_ident()}


@pytest.mark.slow
def test_a_bad_edit_is_refused_and_a_stopped_loop_answers(render_loop):
    loop = render_loop(max_spp=1)
    before = loop.state()
    with pytest.raises(ConvsssError, match="not reachable"):
        loop.submit({"color": [2.0, 0.5, 0.5]})
    assert loop.state() == before
    loop.stop()
    with pytest.raises(ConvsssError, match="stopping"):
        loop.submit({"sigma_a": [0.2, 0.2, 0.2]})
