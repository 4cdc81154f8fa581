"""The integrator's prepared state: render_prepared shades what prepare built, retransport rebuilds the transports
alone (convsss.scene.integrator)."""

import dataclasses

import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.profiles import model_profile
from convsss.scene.params import RenderParams


@pytest.mark.slow
def test_prepare_then_render_prepared_is_render_and_retransport_keeps_the_samples(mi, sphere_scene):
    scene = mi.load_dict(sphere_scene(res=24, spp=1))
    integrator = scene.integrator()
    image = np.array(integrator.render(scene, seed=3))
    assert integrator.prepared is None  # a render does not keep its samples
    integrator.prepare(scene, scene.sensors()[0], 3)
    assert np.array_equal(np.array(integrator.render_prepared(seed=3)), image)
    state = integrator.prepared
    samples, old = state.samples, state.transports[0]
    integrator.retransport()  # the same profiles: the same image, from new transports on the same samples
    assert state.samples is samples and state.transports[0] is not old
    assert set(integrator.stats["seconds"]) == {"transport", "screen"}
    assert np.array_equal(np.array(integrator.render_prepared(seed=3)), image)
    obj = state.objects[0]
    darker = dataclasses.replace(obj, profile=model_profile(
        "dipole", dataclasses.replace(obj.material, sigma_a=obj.material.sigma_a * 4)))
    integrator.retransport([darker])
    assert np.mean(np.array(integrator.render_prepared(seed=3))) < np.mean(image)


@pytest.mark.slow
def test_retransport_refuses_what_changes_the_samples(mi, sphere_scene):
    scene = mi.load_dict(sphere_scene(res=16, spp=1))
    integrator = scene.integrator()
    with pytest.raises(ConvsssError, match="prepare"):
        integrator.retransport()
    integrator.prepare(scene, scene.sensors()[0], 0)
    integrator.retransport(params=RenderParams(accuracy=0.05))
    assert integrator.prepared.transports[0].params["accuracy"] == 0.05
    with pytest.raises(ConvsssError, match="sample_density"):
        integrator.retransport(params=RenderParams(sample_density=2))
    obj = integrator.prepared.objects[0]
    with pytest.raises(ConvsssError, match="eta"):
        integrator.retransport([dataclasses.replace(obj, material=dataclasses.replace(obj.material, eta=1.4))])
