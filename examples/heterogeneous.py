"""Media that vary in space: a veined marble bunny, a sphere of skin over milk and a painted sphere, as scene files.

Run it (`python examples/heterogeneous.py`): it writes to `$CONVSSS_EXAMPLE_OUT` (default `out/heterogeneous`) two
scenes whose interiors are Mitsuba `heterogeneous` media of `gridvolume` volumes, renders each with convsss, and
prints the commands that render their ground truth with `volpathmis` from the same files and compare:

- `veined-marble.xml`: a 20 mm marble bunny crossed by dark veins (an albedo volume, written with
  `mitsuba.VolumeGrid(array).write` and placed over the object by `quick_scene(..., albedo_volume=...)`, as
  `convsss scene --volume` does);
- `skin-over-milk.xml`: a 20 mm sphere, 1.5 mm of skin1 over a whole-milk core (albedo and `sigma_t` volumes);
- `painted-sphere.xml`: a 20 mm sphere whose `convsss_medium` colour is a bitmap (bands of skin and of a dark red,
  on the sphere's own uv) at a 1 mm mean free path; `convsss.load_scene` (every command) makes it the heterogeneous
  medium it stands for, which `convsss reference` renders too.

See docs/guide/scene-files.md ("Media that vary in space") for what convsss does with them and what it does not.
"""

import os
from pathlib import Path

import numpy as np

import convsss

mi = convsss.register()
from convsss.media.dicts import medium_parameters  # noqa: E402  (after registering the variant)
from convsss.scene.quick import demo_mesh, quick_scene  # noqa: E402
from convsss.scene.xmlwriter import scene_to_xml  # noqa: E402

OUT = Path(os.environ.get("CONVSSS_EXAMPLE_OUT", "out/heterogeneous"))
OUT.mkdir(parents=True, exist_ok=True)
SIZE = int(os.environ.get("CONVSSS_EXAMPLE_SIZE", "256"))  # film width and height in pixels


def write_volume(name, cells):
    """Cells (z, y, x, channels) as a Mitsuba grid volume file beside the scenes; its name as they cite it."""
    mi.VolumeGrid(np.ascontiguousarray(cells, dtype=np.float32)).write(str(OUT / name))
    return name  # relative: Mitsuba resolves a scene's file names against the scene's folder


# Veined marble: dark sinuous sheets (albedo 0.9, 0.85, 0.8) through marble's albedo, on 64^3 cells.
marble = convsss.material("marble")
z, y, x = np.meshgrid(*[np.linspace(0.0, 1.0, 64)] * 3, indexing="ij")
vein = np.exp(-(np.sin(9 * x + 3 * np.sin(6 * y) + 2 * np.sin(5 * z)) / 0.25) ** 2)[..., None]
albedo = medium_parameters(marble)["albedo"] * (1 - vein) + np.array([0.9, 0.85, 0.8]) * vein
veined = quick_scene(demo_mesh(), marble, 20.0, SIZE, SIZE, 16, boundary="null",
                     albedo_volume=write_volume("veins.vol", albedo))

# Skin over milk: per cell of a box around the sphere, skin1 within 1.5 mm of the surface, whole milk inside.
skin, milk = convsss.material("skin1"), convsss.material("wholemilk")
radius, n = 10.0, 96
side = 2.04 * radius
centre = (np.arange(n) + 0.5) / n * side - side / 2
depth = radius - np.sqrt(sum(c**2 for c in np.meshgrid(centre, centre, centre, indexing="ij")))[..., None]
outer = depth < 1.5
sigma_s = np.where(outer, skin.sigma_s_prime, milk.sigma_s_prime)
sigma_t = sigma_s + np.where(outer, skin.sigma_a, milk.sigma_a)  # 1/mm; the scene's unit is the mm
scale = float(sigma_t.max())
box = mi.ScalarTransform4f().translate([-side / 2, radius - side / 2, -side / 2]).scale(side)
layered = quick_scene(demo_mesh(), skin, 2 * radius, SIZE, SIZE, 16, boundary="null")
layered["object"] = {
    "type": "sphere", "center": [0.0, radius, 0.0], "radius": radius, "bsdf": {"type": "null"},
    "interior": {"type": "heterogeneous", "scale": scale,
                 "albedo": {"type": "gridvolume", "filename": write_volume("layers-albedo.vol", sigma_s / sigma_t),
                            "to_world": box},
                 "sigma_t": {"type": "gridvolume", "filename": write_volume("layers-sigma_t.vol", sigma_t / scale),
                             "to_world": box}},
}

# A painted sphere: a colour map (total reflectance per texel) on the sphere's uv, bands across its azimuth.
v, u = np.meshgrid((np.arange(128) + 0.5) / 128, (np.arange(256) + 0.5) / 256, indexing="ij")
band = (0.5 + 0.5 * np.cos(2 * np.pi * 4 * u))[..., None]
mi.Bitmap(((1 - band) * np.array([0.75, 0.55, 0.45]) + band * np.array([0.45, 0.08, 0.05])).astype(np.float32)).write(
    str(OUT / "paint.exr"))
painted = quick_scene(demo_mesh(), skin, 2 * radius, SIZE, SIZE, 16, boundary="null")
painted["object"] = {"type": "sphere", "center": [0.0, radius, 0.0], "radius": radius, "bsdf": {"type": "null"},
                     "interior": {"type": "convsss_medium", "color": {"type": "bitmap", "filename": "paint.exr"},
                                  "mfp_mm": 1.0, "eta": 1.0}}

integrator = mi.load_dict({"type": "convsss"})  # the files name volpathmis, their ground truth
for name, scene in (("veined-marble", veined), ("skin-over-milk", layered), ("painted-sphere", painted)):
    path = OUT / f"{name}.xml"
    path.write_text(scene_to_xml(scene))  # volpathmis is the file's integrator: ground truth (plain Mitsuba for the
    # volumes; `convsss reference` for the painted one, whose convsss_medium plain Mitsuba does not know)
    image = convsss.render(convsss.load_scene(path), integrator=integrator, seed=0)
    mi.Bitmap(image).write(str(OUT / f"{name}.exr"))
    mi.Bitmap(image).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, True).write(str(OUT / f"{name}.png"))
    print(f"{path}: {OUT / f'{name}.exr'}; ground truth and the comparison:\n"
          f"  convsss reference {path} -o {OUT / f'{name}-ref'} --spp 1024\n"
          f"  convsss compare {OUT / f'{name}-ref.exr'} {OUT / f'{name}.exr'}")
