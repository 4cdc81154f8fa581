"""The diffusion field the random walk ends in (convsss.pipeline.field): walks ended in it keep the render's mean
(against volpathmis, and against walks to the end), end where they should, and a point light behind a dielectric,
which no walk reaches, stays lit (Eq. W4) as walks to the end light it."""

import numpy as np
import pytest

from convsss.pipeline.reference import reference_integrator, translucent_pixels

RES, SPP = 32, 128


def _area_light(mi, radius):
    return {"light": {"type": "rectangle",
                      "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [4.0] * 3}},
                      "to_world": mi.ScalarTransform4f().look_at(origin=[0, 3 * radius, 4 * radius], target=[0, 0, 0],
                                                                 up=[0, 1, 0]).scale(1.5 * radius)}}


def _render(mi, scene, integrator, seeds):
    return [np.array(mi.render(scene, integrator=integrator, spp=SPP, seed=s), dtype=np.float64)[..., :3]
            for s in seeds]


@pytest.mark.slow
def test_walks_ended_in_the_field_keep_the_mean_of_volpathmis_and_are_shorter(mi, sphere_scene):
    scene = mi.load_dict(sphere_scene(material="wholemilk", radius=5.0, boundary="null", res=RES,
                                      emitters=_area_light(mi, 5.0)))
    inside = translucent_pixels(scene)
    truth = np.mean([image[inside].mean(axis=0) for image in _render(mi, scene, reference_integrator(), (1, 2))],
                    axis=0)
    ended = mi.load_dict({"type": "convsss", "walk_depth": 4.0, "max_depth": -1})
    ours = np.mean([image[inside].mean(axis=0) for image in _render(mi, scene, ended, (3, 4))], axis=0)
    walk = ended.stats["walk"]
    full = mi.load_dict({"type": "convsss", "walk_depth": float("inf"), "max_depth": -1})
    _render(mi, scene, full, (5,))
    assert np.all(np.abs(ours / truth - 1.0) < 0.03), ours / truth
    assert walk["ended_share"] > 0.01 and walk["capped_share"] == 0.0
    assert walk["events_per_path"] < 0.8 * full.stats["walk"]["events_per_path"]


@pytest.mark.slow
def test_a_point_light_behind_a_dielectric_stays_lit_as_walks_to_the_end_light_it(mi, sphere_scene):
    """A large sphere of high albedo (diffusion right there) under a point light, behind a smooth dielectric, which
    no path reaches: walks ended in the field render it as walks to their end do, both lit through Eq. W4 (checked
    against volpathmis under a finite light in tests/pipeline/test_walk.py). Measured: 1.015-1.031 (the field's
    extrapolated boundary from the Fresnel moments; 1.03-1.047 with the classic dipole's); the transport 0.95-0.96."""
    scene = mi.load_dict(sphere_scene(material="marble", radius=20.0, boundary="dielectric", res=RES))
    inside = translucent_pixels(scene)
    def mean(depth, seeds):
        integrator = mi.load_dict({"type": "convsss", "walk_depth": depth})
        return np.mean([image[inside].mean(axis=0) for image in _render(mi, scene, integrator, seeds)], axis=0)

    ratio = mean(4.0, (3, 4)) / mean(np.inf, (1, 2))
    assert np.all(np.abs(ratio - 1.0) < 0.04), ratio


@pytest.mark.slow
@pytest.mark.parametrize("material", ["marble", "wholemilk"])
def test_the_fluence_deep_inside_is_what_walks_from_there_find(mi, material):
    """Deep inside a 10 mm sphere (5-7 mm, 12-20 transport mean free paths) under an environment, the field's
    fluence against 4 pi times the mean radiance that walks to their end bring to the point (every direction)."""
    import drjit as dr

    import convsss
    from convsss.media.dicts import translucent
    from convsss.pipeline.params import RenderMode
    from convsss.pipeline.walk import RandomWalk

    radius, T = 10.0, mi.ScalarTransform4f
    scene = mi.load_dict({"type": "scene", "environment": {"type": "constant"},
                          "sensor": {"type": "perspective", "fov": 30, "film": {"type": "hdrfilm", "width": 32,
                                                                                  "height": 32},
                                     "to_world": T().look_at(origin=[0, 20, 80], target=[0, 0, 0], up=[0, 1, 0])},
                          "object": translucent({"type": "sphere", "radius": radius}, convsss.material(material),
                                                boundary="null")})
    integrator = mi.load_dict({"type": "convsss", "walk_depth": 2.0})
    integrator.prepare(scene, scene.sensors()[0], 0)
    tracer = integrator.session.tracer
    points = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, -3.0, 3.0], [-2.0, 3.5, -1.0]])
    depth, fluence = tracer.walk.field.fluence(0, points)
    assert np.all(depth > 5.0)
    walk = RandomWalk(scene, tracer.objects, tracer.params, RenderMode(float("inf")))  # no field: walks to their end
    found = []
    for k, point in enumerate(points):
        sampler = mi.load_dict({"type": "independent"})
        sampler.seed(k, 1 << 14)
        direction = mi.warp.square_to_uniform_sphere(sampler.next_2d())
        radiance, _ = walk.trace(sampler, mi.Ray3f(mi.Point3f(*point.tolist()), direction),
                                 scene.shapes()[0].interior_medium())
        found.append(4.0 * np.pi * dr.ravel(radiance).numpy().reshape(-1, 3).mean(axis=0))
    assert np.all(np.abs(fluence.mean(axis=0) / np.mean(found, axis=0) - 1.0) < 0.03)


def test_a_field_far_coarser_than_walk_depth_asks_is_said():
    """Issue 62: on a 1e5 mm object at walk_depth 2 the grid (at its node cap) has cells of hundreds of mm, so no walk
    ended in the field, and nothing said so."""
    import types
    import warnings

    import convsss
    from convsss.pipeline.field import CoarseFieldWarning, _check_resolution, field_spacing

    material = convsss.material("wholemilk")
    for size_mm, warned in ((1e5, True), (20.0, False)):
        obj = types.SimpleNamespace(name="big", material=material)
        spacing = field_spacing(np.array([[0.0] * 3, [size_mm] * 3]), material, 2.0)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            _check_resolution(obj, spacing, 2.0)
        assert [issubclass(w.category, CoarseFieldWarning) for w in caught] == [True] * warned, size_mm
    assert spacing < 1.0 and field_spacing(np.array([[0.0] * 3, [1e5] * 3]), material, 2.0) > 100.0
