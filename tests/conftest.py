"""Tiny scenes for the renderer's tests: a sphere of a preset material seen by a small camera."""

import pytest

import convsss
from convsss.media.dicts import translucent


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
