"""Variations of a loaded scene (convsss.scene.variations): lights scaled, the camera orbited."""

import numpy as np
import pytest

import convsss
from convsss.errors import ConvsssError
from convsss.scene.variations import orbit_camera, scale_lights


def _lights(mi):
    T = mi.ScalarTransform4f
    return {"type": "scene",
            "point": {"type": "point", "position": [1, 2, 3], "intensity": {"type": "rgb", "value": [2, 3, 4]}},
            "sky": {"type": "constant", "radiance": {"type": "rgb", "value": 0.5}},
            "sun": {"type": "directional", "direction": [0, -1, 0], "irradiance": {"type": "rgb", "value": 1.5}},
            "panel": {"type": "rectangle", "to_world": T().translate([0, 5, 0]),
                      "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [1, 2, 3]}}},
            "spot": {"type": "spot", "intensity": {"type": "rgb", "value": 7.0}}}


def _powers(mi, scene):
    out = []
    for emitter in scene.emitters():
        params = mi.traverse(emitter)
        out += [np.array(params[k]).ravel() for k in sorted(params.keys())
                if k.endswith((".value",)) and not k.startswith("texture")]
    return np.concatenate(out)


def test_scale_lights_multiplies_every_emitter_type_power(mi):
    scene = mi.load_dict(_lights(mi))
    before = _powers(mi, scene)
    scale_lights(scene, 2.5)
    np.testing.assert_allclose(_powers(mi, scene), 2.5 * before, rtol=1e-6)
    with pytest.raises(ConvsssError, match="light scale"):
        scale_lights(scene, -1.0)


@pytest.mark.slow
def test_a_scaled_light_scales_the_render(mi, sphere_scene):
    images = []
    for factor in (1.0, 3.0):
        scene = scale_lights(mi.load_dict(sphere_scene(res=16, spp=1)), factor)
        images.append(np.array(convsss.render(scene, seed=1), dtype=np.float64)[..., :3])
    np.testing.assert_allclose(images[1], 3.0 * images[0], rtol=1e-5, atol=1e-7)


def test_orbit_turns_the_camera_about_the_translucent_objects_centre(mi, sphere_scene):
    scene = mi.load_dict(sphere_scene(res=16, spp=1))  # the sphere at the origin, the camera at (0, 4, 16)

    def position():
        return np.array(mi.traverse(scene.sensors()[0])["to_world"].matrix)[:3, 3].ravel()

    start = position()
    orbit_camera(scene, 360.0)
    np.testing.assert_allclose(position(), start)
    orbit_camera(scene, 90.0)
    np.testing.assert_allclose(position(), [start[2], start[1], -start[0]], atol=1e-4)
    orbit_camera(scene, -90.0)
    np.testing.assert_allclose(position(), start, atol=1e-4)
