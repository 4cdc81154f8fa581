"""The integrator's prepared state: render_prepared shades what prepare built, retransport rebuilds the transports
alone (convsss.pipeline.integrator)."""

import dataclasses

import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.pipeline.params import RenderParams
from convsss.profiles import model_profile


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
    integrator.retransport(params=RenderParams(accuracy=0.05, walk_depth=0.0))
    assert integrator.prepared.transports[0].params["accuracy"] == 0.05
    with pytest.raises(ConvsssError, match="sample_density"):
        integrator.retransport(params=RenderParams(sample_density=2, walk_depth=0.0))
    obj = integrator.prepared.objects[0]
    with pytest.raises(ConvsssError, match="eta"):
        integrator.retransport([dataclasses.replace(obj, material=dataclasses.replace(obj.material, eta=1.4))])


def _fresh(mi, scene_dict, **render):
    """The image of a render from nothing: a new scene, its integrator never prepared."""
    import convsss

    return np.array(convsss.render(mi.load_dict(scene_dict), **render))


@pytest.mark.slow
def test_a_prepared_scene_renders_again_reusing_what_still_holds(mi, sphere_scene):
    import convsss

    spec = sphere_scene(res=24, spp=1, floor=True)
    scene = mi.load_dict(spec)
    integrator, sensor = scene.integrator(), scene.sensors()[0]
    integrator.prepare(scene, sensor, 5)
    shaded = np.array(integrator.render_prepared(spp=2, seed=5))
    more = np.array(convsss.render(scene, spp=2, seed=5))  # another spp (here the same): only the shading
    assert integrator.stats["reused"] == ["samples", "irradiance", "indirect", "transport", "screen"]
    assert set(integrator.stats["seconds"]) == {"shading"} and np.array_equal(more, shaded)
    assert integrator.prepared is not None  # still kept
    other = np.array(convsss.render(scene, spp=2, seed=6))  # another seed: fresh samples, the same survey
    assert integrator.stats["reused"] == ["survey"]
    assert np.array_equal(other, _fresh(mi, spec, spp=2, seed=6)) and not np.array_equal(other, shaded)
    params = mi.traverse(sensor)  # a crop window: the same samples and transports, a new survey and screen
    params["film.crop_size"], params["film.crop_offset"] = [12, 10], [6, 8]
    params.update()
    crop = np.array(convsss.render(scene, spp=2, seed=6))
    assert integrator.stats["reused"] == ["irradiance", "indirect", "transport"] and crop.shape[:2] == (10, 12)
    spec_crop = {**spec, "sensor": {**spec["sensor"], "film": {**spec["sensor"]["film"], "crop_width": 12,
                                                                 "crop_height": 10, "crop_offset_x": 6,
                                                                 "crop_offset_y": 8}}}
    assert np.array_equal(crop, _fresh(mi, spec_crop, spp=2, seed=6))


@pytest.mark.slow
def test_a_changed_scene_parameter_or_release_prepares_again(mi, sphere_scene):
    import convsss

    spec = sphere_scene(res=16, spp=1)
    scene = mi.load_dict(spec)
    integrator = scene.integrator()
    integrator.prepare(scene, scene.sensors()[0], 0)
    before = np.array(convsss.render(scene, seed=0))
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("intensity.value"))
    params[key] = params[key] * 2.0
    params.update()
    brighter = np.array(convsss.render(scene, seed=0))
    assert integrator.stats["reused"] == []  # the light changed: the irradiance is drawn again
    assert np.mean(brighter) == pytest.approx(2 * np.mean(before), rel=1e-3)
    integrator.release()
    assert integrator.prepared is None
    again = np.array(convsss.render(scene, seed=0))
    assert integrator.prepared is None and np.array_equal(again, brighter)


def test_scene_fingerprint_follows_the_scene_and_the_crop_apart(mi, sphere_scene):
    from convsss.pipeline.session import scene_fingerprint

    scene = mi.load_dict(sphere_scene(res=16, spp=1, floor=True))
    sensor = scene.sensors()[0]
    world, crop = scene_fingerprint(scene, sensor)
    assert scene_fingerprint(scene, sensor) == (world, crop)  # nothing random, no addresses
    params = mi.traverse(sensor)
    params["film.crop_size"] = [8, 8]
    params.update()
    assert scene_fingerprint(scene, sensor) == (world, ((8, 8), (0, 0)))
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("to_world") and "floor" in k)
    params[key] = mi.ScalarTransform4f().translate([0, -3.0, 0]).rotate([1, 0, 0], -90).scale(40.0)  # moved down
    params.update()
    assert scene_fingerprint(scene, sensor)[0] != world
