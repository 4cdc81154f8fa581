"""Tiny scenes for the renderer's tests: a sphere of a preset material seen by a small camera."""

import numpy as np
import pytest

import convsss
from convsss.media.dicts import medium_dict, translucent


@pytest.fixture(scope="session")
def mi():
    return convsss.register()


@pytest.fixture(scope="session")
def sphere_scene(mi):
    """``sphere_scene(**options)`` -> a scene dictionary: a translucent sphere, a point light, a 48x48 camera; its
    integrator renders with the transport (walk_depth 0) unless ``integrator`` says otherwise."""

    def make(material="skin1", radius=2.0, boundary="null", integrator=None, res=48, spp=2, emitters=None,
             floor=False, extra=None, fov=30.0, unit_mm=1.0):
        """Lengths in mm; with ``unit_mm`` != 1 the scene is written in units of ``unit_mm`` mm (coefficients, lengths
        and the light's intensity converted, so it renders the same image)."""
        T = mi.ScalarTransform4f
        radius = radius / unit_mm
        integrator = {"unit_mm": unit_mm, **(integrator or {})} if unit_mm != 1.0 else (integrator or {})
        scene = {
            "type": "scene",
            "integrator": {"type": "convsss", "walk_depth": 0.0, **integrator},
            "sensor": {"type": "perspective", "fov": fov,
                       "to_world": T().look_at(origin=[0, 2 * radius, 8 * radius], target=[0, 0, 0], up=[0, 1, 0]),
                       "film": {"type": "hdrfilm", "width": res, "height": res, "rfilter": {"type": "box"}},
                       "sampler": {"type": "independent", "sample_count": spp}},
            "object": translucent({"type": "sphere", "radius": radius}, convsss.material(material),
                                  unit_mm=unit_mm, boundary=boundary),
        }
        if emitters is None:
            emitters = {"light": {"type": "point", "position": [3 * radius, 6 * radius, 4 * radius],
                                  "intensity": {"type": "rgb", "value": [50 * radius**2] * 3}}}
        scene.update(emitters)
        if floor:
            scene["floor"] = {"type": "rectangle", "bsdf": {"type": "diffuse"},
                              "to_world": T().translate([0, -radius, 0]).rotate([1, 0, 0], -90).scale(20 * radius)}
        scene.update(extra or {})
        return scene

    return make


@pytest.fixture(scope="session")
def object_mask(mi):
    """``object_mask(scene)`` -> (H, W) bool: pixels whose centre ray hits a translucent shape first."""
    from convsss.pipeline.reference import translucent_pixels

    return translucent_pixels


@pytest.fixture
def object_pair(mi, sphere_scene):
    """``(scene, pixels)``: a 40 mm marble sphere behind glass (diffusion holds) and a 14 mm skin1 one before it (it
    fails: auto walks it and renders the marble by its transport) under a spherical light, 32², convsss's default
    integrator; ``pixels[name]`` (32, 32) bool, ``name`` marble or skin."""
    T = mi.ScalarTransform4f
    light = {"light": {"type": "sphere", "center": [60.0, 120.0, 80.0], "radius": 20.0,
                       "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [50 / np.pi] * 3}}}}
    skin = translucent({"type": "sphere", "radius": 7.0, "to_world": T().translate([24.0, -12.0, 40.0])},
                       convsss.material("skin1"), boundary="dielectric")
    scene = sphere_scene(material="marble", radius=20.0, boundary="dielectric", res=32, emitters=light,
                         extra={"skin": {**skin, "interior": medium_dict(convsss.material("skin1"))}},
                         integrator={"walk_depth": "auto"})
    scene["object"]["interior"] = medium_dict(convsss.material("marble"))
    scene = mi.load_dict(scene)
    index = mi.load_dict({"type": "convsss", "walk_depth": 0.0, "aovs": "object"})
    objects = np.array(mi.render(scene, integrator=index, spp=1))[..., -1]
    return scene, {name: np.isclose(objects, k) for k, name in ((1, "marble"), (2, "skin"))}
