"""Tiny scenes for the renderer's tests: a sphere of a preset material seen by a small camera."""

import numpy as np
import pytest

import convsss
from convsss.scene.materials import translucent


@pytest.fixture(scope="session")
def mi():
    return convsss.register()


@pytest.fixture(scope="session")
def sphere_scene(mi):
    """``sphere_scene(**options)`` -> a scene dictionary: a translucent sphere, a point light, a 48x48 camera."""

    def make(material="skin1", radius=2.0, boundary="null", integrator=None, res=48, spp=2, emitters=None,
             floor=False, extra=None, fov=30.0, unit_mm=1.0):
        """Lengths in mm; with ``unit_mm`` != 1 the scene is written in units of ``unit_mm`` mm (coefficients, lengths
        and the light's intensity converted, so it renders the same image)."""
        T = mi.ScalarTransform4f
        radius = radius / unit_mm
        integrator = {"unit_mm": unit_mm, **(integrator or {})} if unit_mm != 1.0 else (integrator or {})
        scene = {
            "type": "scene",
            "integrator": {"type": "convsss", **integrator},
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
    return lambda scene: _object_mask(mi, scene)


def _object_mask(mi, scene):
    import drjit as dr

    sensor = scene.sensors()[0]
    w, h = (int(x) for x in sensor.film().crop_size())
    y, x = np.mgrid[0:h, 0:w]
    pos = mi.Point2f(((x.ravel() + 0.5) / w).astype(np.float32), ((y.ravel() + 0.5) / h).astype(np.float32))
    ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    si = scene.ray_intersect(ray)
    medium = si.shape.interior_medium()
    hit = si.is_valid() & (dr.reinterpret_array(mi.UInt32, medium) != 0)
    return hit.numpy().reshape(h, w)
