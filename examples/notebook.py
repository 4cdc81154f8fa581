# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # convsss from Python, as a Mitsuba 3 user works
#
# Open `examples/notebook.ipynb` in Jupyter (images inline), or run this file, its source in jupytext's percent
# format, as a script (`python examples/notebook.py`); the test suite runs it and checks that the `.ipynb` holds the
# same cells (`tests/test_examples.py`; after an edit, `.venv/bin/jupytext --to ipynb examples/notebook.py`). Images
# and plots go to `$CONVSSS_EXAMPLE_OUT` (default `out/notebook`).
#
# It registers the integrator, builds a scene dictionary with a translucent object (a material preset named in
# the scene, `convsss_medium`), an opaque floor, an area light and an environment map, renders it with AOVs, changes
# the material in a loop reusing everything the material does not change, and plots the diffusion profiles.

# %%
import os
from dataclasses import replace
from pathlib import Path

import numpy as np

import convsss

mi = convsss.register()  # the active Mitsuba variant if convsss supports it, else llvm_ad_rgb
OUT = Path(os.environ.get("CONVSSS_EXAMPLE_OUT", "out/notebook"))
OUT.mkdir(parents=True, exist_ok=True)
SIZE = int(os.environ.get("CONVSSS_EXAMPLE_SIZE", "128"))  # film width and height in pixels


def show(path):
    """The image at ``path`` inline in Jupyter; nothing when run as a script."""
    try:
        from IPython import get_ipython
        from IPython.display import Image, display
    except ImportError:
        return
    if get_ipython() is not None:
        display(Image(filename=str(path)))

# %% [markdown]
# ## A scene dictionary
# Lengths in mm (the integrator's `unit_mm` is 1). The sphere's interior names a preset; its boundary is a smooth
# dielectric with the preset's index of refraction (`convsss materials` lists both).

# %%
milk = convsss.material("wholemilk")
sky = np.full((16, 32, 3), 0.2, dtype=np.float32)
sky[:8] *= 2.0  # a brighter upper half

scene_dict = {
    "type": "scene",
    "integrator": {"type": "convsss", "aovs": "exitance,mask"},  # extra film channels besides RGB
    "sensor": {
        "type": "perspective",
        "fov": 30,
        "to_world": mi.ScalarTransform4f().look_at(origin=[0, 25, 90], target=[0, 8, 0], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE, "rfilter": {"type": "gaussian"}},
        "sampler": {"type": "independent", "sample_count": 4},
    },
    "sphere": {
        "type": "sphere", "center": [0, 10, 0], "radius": 10,
        "bsdf": {"type": "dielectric", "int_ior": float(milk.eta), "ext_ior": 1.0},
        "interior": {"type": "convsss_medium", "preset": "wholemilk"},
    },
    "floor": {
        "type": "rectangle",
        "to_world": mi.ScalarTransform4f().rotate([1, 0, 0], -90).scale([60, 60, 1]),
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}},
    },
    "lamp": {
        "type": "rectangle",
        "to_world": mi.ScalarTransform4f().look_at(origin=[30, 60, 30], target=[0, 0, 0], up=[0, 1, 0])
        @ mi.ScalarTransform4f().scale([10, 10, 1]),
        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [20, 20, 20]}},
    },
    "sky": {"type": "envmap", "bitmap": mi.Bitmap(sky)},
}
scene = mi.load_dict(scene_dict, optimize=False)  # optimize=False: Mitsuba would merge shapes of one material

# %% [markdown]
# ## Render, with AOVs
# `convsss.render` is `mi.render` with the integrator's own one-line errors. The film holds RGB, then the AOVs'
# channels in the order `integrator.aov_names()` lists them: here the exitance `M` (paper Eq. 7's, before Fresnel
# and `1/pi`) and the translucent objects' coverage. The integrator's `stats` hold the seconds of each stage, the
# objects (size in mean free paths, samples, flux) and each transport's statistics.

# %%
image = np.asarray(convsss.render(scene, seed=0))
integrator = scene.integrator()
channels = dict(zip(["R", "G", "B"] + integrator.aov_names(), np.moveaxis(image, -1, 0)))
rgb = image[..., :3]
mask = channels["mask.Y"] > 0.5
exitance = np.stack([channels[f"exitance.{c}"] for c in "RGB"], axis=-1)
mi.util.write_bitmap(str(OUT / "milk.png"), rgb)
mi.util.write_bitmap(str(OUT / "milk-mask.png"), mask.astype(np.float32))
show(OUT / "milk.png")
print("sphere pixels", int(mask.sum()), "mean RGB", np.round(rgb[mask].mean(axis=0), 4),
      "mean exitance M", np.round(exitance[mask].mean(axis=0), 4))
print({stage: round(seconds, 3) for stage, seconds in integrator.stats["seconds"].items()})
sphere = integrator.stats["objects"][0]
print(sphere["name"], "samples", sphere["samples"], "mean free paths across", np.round(sphere["mean_free_paths"], 1))

# %% [markdown]
# ## Change the material, keep the rest
# `prepare()` builds the samples, their irradiance and the transports and keeps them in `integrator.prepared`;
# `render_prepared()` shades. A new material of the same index of refraction and reduced albedo needs only the
# transports built again (`retransport`, paper Eq. 1) and the shading: the irradiance (Eq. 2) depends on the material
# through Fresnel's `F_t(eta)` and the albedo's oblique-incidence gain only. Scaling every coefficient keeps the
# albedo and the colour and sets the mean free path.

# %%
integrator.prepare(scene, scene.sensors()[0], seed=0)
obj = integrator.prepared.objects[0]
means = {}
for mfp in (0.5, 2.0, 8.0):  # the same colour, light travelling farther and farther
    k = obj.material.mfp_mm / mfp  # per channel: sigma_t' = 1 / mfp
    new = replace(obj.material, sigma_s_prime=obj.material.sigma_s_prime * k, sigma_a=obj.material.sigma_a * k)
    integrator.retransport(objects=[replace(obj, material=new, profile=convsss.model_profile("dipole", new))])
    edited = np.asarray(integrator.render_prepared())[..., :3]
    mi.util.write_bitmap(str(OUT / f"mfp-{mfp:g}mm.png"), edited)
    show(OUT / f"mfp-{mfp:g}mm.png")
    means[mfp] = edited[mask].mean(axis=0)  # over the sphere's pixels
    seconds = integrator.stats["seconds"]["transport"]
    print(f"mfp {mfp:g} mm: sphere's mean RGB {np.round(means[mfp], 4)}, transport {seconds:.2f} s")

# %% [markdown]
# ## Profiles
# The radial profile `R_d(r)` of each model for the preset, as `convsss profile plot` draws it.

# %%
from convsss.profiles.models import PROFILE_MODELS  # noqa: E402
from convsss.profiles.plot import plot_profiles  # noqa: E402

plot_profiles([("wholemilk", [(model, convsss.model_profile(model, milk)) for model in PROFILE_MODELS])],
              OUT / "profiles.png")
show(OUT / "profiles.png")
print("wrote", sorted(p.name for p in OUT.iterdir()))
