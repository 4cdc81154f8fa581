"""The sampling plan (:mod:`convsss.scene.plan`): counts and budgets decided from what is known before any sample is
drawn, and refusals that come before any work (issue 30: a dense material was refused after 22.8 M samples)."""

import numpy as np
import pytest

import convsss
from convsss.errors import ConvsssError
from convsss.scene import irradiance
from convsss.scene.quick import demo_mesh, quick_scene


def _bunny(mi, material, size_mm, res=96, **integrator):
    d = quick_scene(demo_mesh(), convsss.material(material), size_mm, res, res, 1,
                    integrator={"type": "convsss", **integrator})
    return mi.load_dict(d)


def _no_sampling(monkeypatch):
    """Make drawing samples fail: a refusal that comes after it is a test failure."""
    from convsss.scene import lighting as module

    def drawn(*args, **kwargs):
        raise AssertionError("samples were drawn before the refusal")

    monkeypatch.setattr(module, "object_samples", drawn)
    monkeypatch.setattr(irradiance, "sample_surface", drawn)


@pytest.mark.filterwarnings("ignore::convsss.scene.plan.SampleNoiseWarning")
def test_a_dense_medium_whose_far_field_does_not_fit_is_refused_before_any_sample(mi, monkeypatch):
    """The 40 mm spectralon bunny at 96² (issue 30, defect 1): its multiscale far-field mesh alone needs more than
    the machine has; the plan knows it from the profile and the object's extent."""
    from convsss.memory import available_memory

    scene = _bunny(mi, "spectralon", 40.0)
    _no_sampling(monkeypatch)
    integrator = scene.integrator()
    if available_memory() is None:
        pytest.skip("no MemAvailable on this machine")
    with pytest.raises(ConvsssError, match=r"mean free paths across.*multiscale transport need about .* GiB"):
        integrator.prepare(scene, scene.sensors()[0], 0)


def test_an_object_far_too_large_for_its_units_is_refused_at_once_naming_its_span(mi, monkeypatch):
    """A unit mistake, an object 1000 times too large (issue 30, defect 9): one line before any work, naming its
    size in mean free paths and unit_mm."""
    scene = _bunny(mi, "wholemilk", 4e4)
    _no_sampling(monkeypatch)
    with pytest.raises(ConvsssError, match=r"mean free paths across, unit_mm = 1\).* need about"), \
            pytest.warns(UserWarning):
        scene.integrator().prepare(scene, scene.sensors()[0], 0)


@pytest.mark.slow
def test_the_plan_is_what_the_render_draws(mi):
    """The counts and the cell of the plan are those the prepared state holds, and its transport bytes bound the
    far-field mesh the multiscale transport built."""
    from convsss.scene.plan import plan_samples
    from convsss.transport.multiscale import far_bytes

    scene = _bunny(mi, "wholemilk", 20.0, res=48)
    integrator = scene.integrator()
    integrator.prepare(scene, scene.sensors()[0], 0)
    state = integrator.prepared
    from convsss.scene.camera import first_hits

    seen = first_hits(scene, state.sensor, state.frame, 1.0, state.objects)
    (plan,) = plan_samples(scene, state.sensor, state.frame, state.objects, seen, integrator.params).objects
    stats = integrator.stats["objects"][0]
    assert stats["samples"] == len(state.samples[0]) >= plan.samples
    assert stats["samples"] == int(np.ceil(np.sqrt(plan.samples))) ** 2  # a stratified k x k square
    assert plan.pixel_footprint_mm == state.cells[0] == stats["pixel_footprint_mm"]
    built = far_bytes(state.transports[0].fft_shape)
    assert built <= plan.transport_bytes <= 1.3 * built + 2**20
    view = state.frame.to_view(state.samples[0].position)
    assert np.all(plan.bounds_mm[0] <= view.min(axis=0) + 1e-6) and np.all(view.max(axis=0) <= plan.bounds_mm[1] + 1e-6)
