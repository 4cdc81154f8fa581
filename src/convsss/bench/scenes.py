"""The benchmark's scenes and how a case (samples and visible points) is prepared from one, as a render would.

Importing this module is cheap (no Mitsuba, no numba): the command line lists :data:`SCENES` in its help.
"""

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Visible points at which the exact sum is the reference (a fixed random subset where there are more).
REFERENCE_POINTS = 20000
#: The test meshes beside the repository (``../shared/data/meshes``); the bunny is also bundled with the package.
MESHES = Path(__file__).resolve().parents[3].parent / "shared" / "data" / "meshes"


@dataclass(frozen=True)
class BenchScene:
    """A benchmark scene: a mesh (``bunny``: the bundled one; else a file in :data:`MESHES`), a material (a preset's
    name, or a colour and a mean free path: :func:`bench_material`), the object's size, and its lighting:
    ``key+back`` (index-matched boundary, the quick scene's two point lights), ``back`` (the back light alone: lit
    from behind), ``area`` (a smooth dielectric under a square area light at the key light's place and a dim
    constant environment), ``side`` (the same light beside the object, level with its centre, at right angles to
    the camera: thin parts seen against it), ``sun`` (a rough dielectric, roughness 0.3, under a sun, a directional
    light from the key light's side, and a sky, a constant environment), ``environment`` (a smooth dielectric
    under a constant environment alone) or ``sunmap`` (a smooth dielectric under an environment map of a dim sky and
    a small sun: :func:`~convsss.bench.lights.write_sun_sky`). A ``companion`` ``(material, diameter_mm)`` adds a
    sphere of that material, with the same boundary, in front of the object on the camera's right: a second object,
    rendered its own way."""

    mesh: str
    material: str
    size_mm: float
    lighting: str = "key+back"
    companion: tuple = ()


#: The lightings whose boundary is a smooth dielectric, and a rough one (the rest: index-matched).
DIELECTRIC_LIGHTINGS = ("area", "side", "environment", "sunmap")
ROUGH_LIGHTINGS = ("sun",)


def bench_material(spec):
    """A benchmark's material: a preset's name, or ``(colour, mfp_mm)``, the exact total reflectance per channel and
    one reduced mean free path (eta 1.3)."""
    from ..materials import material
    from ..profiles.models import material_from_color

    if isinstance(spec, str):
        return material(spec)
    color, mfp = spec
    return material_from_color(color, mfp, 1.3, "exact", name="colour", warn=False)


SCENES = {
    "bunny40": BenchScene("bunny", "wholemilk", 40.0),
    "bunny4": BenchScene("bunny", "wholemilk", 4.0),
    "armadillo60-back": BenchScene("armadillo.obj", "marble", 60.0, "back"),
    "bust200": BenchScene("decimated-max.obj", "skin1", 200.0),
    "dragon60": BenchScene("dragon.ply", "apple", 60.0, "area"),
}


def scene_dict(scene, resolution=800):
    """The Mitsuba scene dictionary of a :class:`BenchScene` (or the name of one in :data:`SCENES`)."""
    from ..errors import ConvsssError
    from ..scene.quick import demo_mesh, mesh_bounds, quick_scene

    if isinstance(scene, str):
        if scene not in SCENES:
            raise ConvsssError(f"benchmark scene {scene!r}: choose one of {', '.join(SCENES)}")
        scene = SCENES[scene]
    mesh = demo_mesh() if scene.mesh == "bunny" else MESHES / scene.mesh
    if not mesh.is_file():
        raise ConvsssError(f"benchmark mesh {str(mesh)!r} is missing (the test meshes live in ../shared/data/meshes)")
    lighting, size_mm = scene.lighting, scene.size_mm
    boundary = ("dielectric" if lighting in DIELECTRIC_LIGHTINGS else
                "roughdielectric" if lighting in ROUGH_LIGHTINGS else "null")
    out = quick_scene(mesh, bench_material(scene.material), size_mm, resolution, resolution, boundary=boundary)
    if lighting == "back":
        out.pop("key_light")
    if lighting in DIELECTRIC_LIGHTINGS + ROUGH_LIGHTINGS:
        from ..backend import load_mitsuba

        transform = load_mitsuba().ScalarTransform4f
        lo, hi = mesh_bounds(mesh)
        centre = np.array([0.0, 0.5 * size_mm * float((hi - lo)[1] / np.max(hi - lo)), 0.0])  # quick_scene's layout
        key = np.asarray(out.pop("key_light")["position"])
        out.pop("back_light")
        distance = float(np.linalg.norm(key - centre))
    if lighting == "sun":
        out["object"]["bsdf"]["alpha"] = 0.3
        out["sun"] = {"type": "directional", "direction": (centre - key).tolist(),
                      "irradiance": {"type": "rgb", "value": [1.0] * 3}}
        out["sky"] = {"type": "constant", "radiance": {"type": "rgb", "value": [0.2] * 3}}
    elif lighting == "environment":
        out["environment"] = {"type": "constant", "radiance": {"type": "rgb", "value": [1.0] * 3}}
    elif lighting == "sunmap":
        from .lights import write_sun_sky

        out["environment"] = {"type": "envmap", "filename": str(write_sun_sky())}
    elif lighting in ("area", "side"):
        # A square light facing the object (a rectangle emits along its +z), irradiance about 1 at the object,
        # and a dim environment that lights the back.
        at = key if lighting == "area" else centre + [distance, 0.0, 0.0]
        side = 0.5 * size_mm
        radiance = distance**2 / side**2
        to_world = transform().look_at(origin=np.asarray(at).tolist(), target=centre.tolist(), up=[0.0, 1.0, 0.0])
        out["area_light"] = {"type": "rectangle", "to_world": to_world @ transform().scale([side / 2, side / 2, 1]),
                             "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [radiance] * 3}}}
        out["environment"] = {"type": "constant", "radiance": {"type": "rgb", "value": [0.05] * 3}}
    if scene.companion:
        from ..media.dicts import translucent

        companion, diameter = scene.companion
        radius = 0.5 * float(diameter)
        at = [0.35 * size_mm, radius, 0.45 * size_mm + radius]  # clear of the object's box (quick_scene's layout)
        out["companion"] = translucent({"type": "sphere", "radius": radius, "center": at}, bench_material(companion),
                                       boundary=boundary)
    return out


def prepare_case(scene_dict, sample_density=4.0, seed=0, profile=""):
    """Samples and visible points of the scene's (first) translucent object, prepared by the render's own stages
    (:func:`~convsss.pipeline.plan.plan_samples`, :func:`~convsss.pipeline.lighting.light_samples`: the same sample
    counts, direct and indirect irradiance), its profile chosen by ``profile`` (the integrator's ``profile`` parameter;
    empty: the default model), at the render's defaults but ``sample_density``.

    Returns a dict: ``samples`` (IrradianceSamples), ``points`` (K, 3) mm, their outward ``normals`` (the visible
    pixel centres of :func:`~convsss.pipeline.camera.first_hits`), ``profile``, ``frame`` (ViewFrame), ``cell_size``
    (mm, the pixel footprint at the object), ``object`` (its summary and plan) and ``prepare_s`` (seconds).
    """
    from ..backend import load_mitsuba
    from ..errors import ConvsssError
    from ..pipeline.camera import first_hits, sensor_frame
    from ..pipeline.lighting import light_samples
    from ..pipeline.objects import find_translucent_objects
    from ..pipeline.params import RenderParams, render_mode
    from ..pipeline.path_tracer import PathTracer
    from ..pipeline.plan import plan_samples
    from ..samples import IrradianceSamples
    from ..scene.loading import load_scene

    mi = load_mitsuba()
    start = time.perf_counter()
    scene = load_scene(scene_dict)
    params = RenderParams(transport="exact", sample_density=sample_density, profile=profile)
    sensor = scene.sensors()[0]
    frame = sensor_frame(sensor, params.unit_mm)
    obj = find_translucent_objects(mi, scene, params.unit_mm, params.profile, params.profile_total,
                                   params.orders)[0]
    (seen,) = first_hits(scene, sensor, frame, params.unit_mm, [obj])
    mode = render_mode(params, [obj])
    plan = plan_samples(scene, sensor, frame, [obj], [seen], params, mode)
    if not plan.objects:
        raise ConvsssError("the benchmark scene's object is not visible from its camera")
    lighting = light_samples(scene, [obj], plan, params, seed, PathTracer(scene, [obj], params, mode))
    s, (q,) = lighting.samples[0], plan.objects
    samples = IrradianceSamples(s.position, s.area, lighting.irradiance[0], s.normal)
    width, height = (int(x) for x in sensor.film().crop_size())
    return {"samples": samples, "points": np.ascontiguousarray(seen.position),
            "normals": np.ascontiguousarray(seen.normal * obj.orientation), "profile": obj.profile,
            "frame": frame, "cell_size": q.pixel_footprint_mm,
            "object": {**obj.summary(), **q.summary(obj.area_mm2), "samples": len(samples)},
            "image": [width, height], "prepare_s": time.perf_counter() - start}
