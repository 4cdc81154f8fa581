"""Indirect light against volpathmis (docs/benchmarks.md): mean(convsss) / mean(volpathmis) over the object's pixels,
per scene, with its surroundings (floor, box walls, a second object) and without them.

    PYTHONPATH=src python docs/history/scripts/indirect-ratio.py SCENES INDIRECT_SAMPLES [SPP [INTEGRATOR_JSON]]

SCENES: comma-separated names (see SCENES, and milk-pair) or all; INDIRECT_SAMPLES: comma-separated values; SPP: the
volpathmis references' samples per pixel (default 64), cached in out/indirect-cache/; INTEGRATOR_JSON: more convsss
parameters, e.g. '{"max_depth": -1}' (the references are unbounded). Images are 128 x 128.
"""

import hashlib
import json
import sys
import time
from pathlib import Path

import drjit as dr
import numpy as np

import convsss
from convsss.media.dicts import translucent
from convsss.scene.quick import demo_mesh, quick_scene
from convsss.pipeline.reference import render_reference

mi = convsss.register()

T = mi.ScalarTransform4f
RES = 128


def diffuse(v):
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [v] * 3}}


def bunny(material, floor, white=False):
    d = quick_scene(demo_mesh(), convsss.material(material), 40, RES, RES, 16, floor=floor, boundary="null")
    if floor and white:
        d["floor"]["bsdf"] = diffuse(0.8)
    return d


def base(objects, emitters, extra, origin=(0, 20, 60), target=(0, 5, 0), fov=35):
    d = {
        "type": "scene",
        "sensor": {
            "type": "perspective",
            "fov": fov,
            "to_world": T().look_at(origin=list(origin), target=list(target), up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": RES, "height": RES, "rfilter": {"type": "gaussian"}},
            "sampler": {"type": "independent", "sample_count": 16},
        },
    }
    d.update(objects)
    d.update(emitters)
    d.update(extra)
    return d


def sphere_floor(material, floor):
    objs = {
        "object": translucent(
            {"type": "sphere", "radius": 10.0, "to_world": T().translate([0, 10, 0])},
            convsss.material(material),
            boundary="null",
        )
    }
    em = {"light": {"type": "point", "position": [-25, 40, 30], "intensity": {"type": "rgb", "value": [2500.0] * 3}}}
    ex = (
        {"floor": {"type": "rectangle", "bsdf": diffuse(0.5), "to_world": T().rotate([1, 0, 0], -90).scale(400)}}
        if floor
        else {}
    )
    return base(objs, em, ex)


def box(material, walls):
    """A 20 mm sphere in a closed 100 mm box (reflectance 0.7), one small point light under the ceiling."""
    objs = {
        "object": translucent(
            {"type": "sphere", "radius": 10.0, "to_world": T().translate([0, 10, 0])},
            convsss.material(material),
            boundary="null",
        )
    }
    em = {"light": {"type": "point", "position": [-20, 80, 10], "intensity": {"type": "rgb", "value": [6000.0] * 3}}}
    ex = {}
    if walls:
        ex["box"] = {
            "type": "cube",
            "flip_normals": True,
            "bsdf": diffuse(0.7),
            "to_world": T().translate([0, 45, 0]).scale(50),
        }
    return base(objs, em, ex, origin=(0, 30, 45), target=(0, 10, 0), fov=40)


def pair(material, which):
    """Two 20 mm spheres 4 mm apart, lit from above-left; which: 'both', 'left', 'right'."""
    objs = {}
    if which in ("both", "left"):
        objs["a"] = translucent(
            {"type": "sphere", "radius": 10.0, "to_world": T().translate([-12, 10, 0])},
            convsss.material(material),
            boundary="null",
        )
    if which in ("both", "right"):
        objs["b"] = translucent(
            {"type": "sphere", "radius": 10.0, "to_world": T().translate([12, 10, 0])},
            convsss.material(material),
            boundary="null",
        )
    em = {"light": {"type": "point", "position": [-40, 50, 20], "intensity": {"type": "rgb", "value": [4000.0] * 3}}}
    return base(objs, em, {}, origin=(0, 20, 70), target=(0, 10, 0))


def mask_of(scene):
    sensor = scene.sensors()[0]
    w, h = (int(x) for x in sensor.film().crop_size())
    y, x = np.mgrid[0:h, 0:w]
    pos = mi.Point2f(((x.ravel() + 0.5) / w).astype(np.float32), ((y.ravel() + 0.5) / h).astype(np.float32))
    ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    si = scene.ray_intersect(ray)
    hit = si.is_valid() & (dr.reinterpret_array(mi.UInt32, si.shape.interior_medium()) != 0)
    return hit.numpy().reshape(h, w)


def reference(name, d, spp):
    key = hashlib.sha1((json.dumps(str(d)) + str(spp)).encode()).hexdigest()[:12]
    Path("out/indirect-cache").mkdir(parents=True, exist_ok=True)
    path = f"out/indirect-cache/{name}-{key}.npy"
    try:
        return np.load(path)
    except FileNotFoundError:
        t = time.time()
        img = render_reference(mi.load_dict(d), spp)
        np.save(path, img)
        print(f"  [{name}: volpathmis {spp} spp in {time.time() - t:.0f} s]", flush=True)
        return img


def convsss_render(d, params, seed=0):
    scene = mi.load_dict({**d, "integrator": {"type": "convsss", **params}})
    img = np.array(scene.integrator().render(scene, scene.sensors()[0], seed=seed), dtype=np.float64)[..., :3]
    return img, scene.integrator().stats, mask_of(scene)


def env(material, _):
    """The box's sphere under uniform diffuse light (a constant environment), nothing else: the profile's bias under
    diffuse illumination."""
    objs = {
        "object": translucent(
            {"type": "sphere", "radius": 10.0, "to_world": T().translate([0, 10, 0])},
            convsss.material(material),
            boundary="null",
        )
    }
    return base(
        objs,
        {"sky": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0] * 3}}},
        {},
        origin=(0, 30, 45),
        target=(0, 10, 0),
        fov=40,
    )


SCENES = {
    "milk-sphere-env": lambda s: env("wholemilk", s),
    "skin-sphere-env": lambda s: env("skin1", s),
    "milk-bunny": lambda s: bunny("wholemilk", s),
    "marble-bunny-white": lambda s: bunny("marble", s, white=True),
    "potato-sphere": lambda s: sphere_floor("potato", s),
    "milk-sphere-box": lambda s: box("wholemilk", s),
    "skin-sphere-box": lambda s: box("skin1", s),
}


def ratio(ref, img, mask):
    return img[mask].mean(axis=0) / ref[mask].mean(axis=0)


if __name__ == "__main__":
    names = sys.argv[1].split(",") if len(sys.argv) > 1 and sys.argv[1] != "all" else list(SCENES) + ["milk-pair"]
    settings = [float(x) for x in (sys.argv[2].split(",") if len(sys.argv) > 2 else ["0", "1"])]
    spp = int(sys.argv[3]) if len(sys.argv) > 3 else 64
    extra = json.loads(sys.argv[4]) if len(sys.argv) > 4 else {}
    for name in names:
        if name == "milk-pair":
            variants = {
                "with": pair("wholemilk", "both"),
                "alone-l": pair("wholemilk", "left"),
                "alone-r": pair("wholemilk", "right"),
            }
        else:
            variants = {"with": SCENES[name](True), "alone": SCENES[name](False)}
        refs = {k: reference(f"{name}-{k}", d, spp) for k, d in variants.items()}
        for ind in settings:
            row = []
            for k, d in variants.items():
                t = time.time()
                img, stats, mask = convsss_render(d, {"indirect_samples": ind, **extra})
                if k == "with" and name == "milk-pair":  # each sphere on its own: a on the left half, b on the right
                    half = np.arange(mask.shape[1]) < mask.shape[1] // 2
                    for side, m in (("l", mask & half[None, :]), ("r", mask & ~half[None, :])):
                        r = ratio(refs[k], img, m)
                        row.append(f"with-{side} {r[0]:.3f}/{r[1]:.3f}/{r[2]:.3f}")
                    continue
                r = ratio(refs[k], img, mask)
                row.append(f"{k} {r[0]:.3f}/{r[1]:.3f}/{r[2]:.3f} ({time.time() - t:.1f}s)")
            print(f"{name:20s} indirect_samples={ind:<5g} " + "  ".join(row), flush=True)
