"""Each light alone: convsss against ``volpathmis`` per medium, emitter type and boundary (issue 37's matrix).

A sphere of one material at the origin, lit by one emitter of one Mitsuba type, null or dielectric boundary, seen by
a small camera with a box filter: the ratio per channel of convsss's mean over the pixels inside the sphere's
silhouette to ``volpathmis``'s (Russian roulette off, as in ``convsss reference``: at an albedo near 1 its weights
are heavy-tailed and a short run's mean falls low, markedly on marble). Two seeds each; the noise of each is its
seeds' difference. A point, spot or directional light behind a smooth dielectric cannot be reached by a
unidirectional path tracer (its image is black), so the dielectric rows take the lights with an area: ``area``,
``constant`` and ``envmap``.

    convsss bench lights [--material ketchup --emitter constant ...]
"""

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.ndimage

from ..files import atomic_write

#: The emitter types, each placed as :func:`emitter_dict` says.
EMITTERS = ("point", "spot", "directional", "area", "constant", "envmap")
#: Those a path tracer reaches through a smooth dielectric.
AREA_EMITTERS = ("area", "constant", "envmap")
#: Low, middle and high albedo (ketchup: 0.75 / 0.07 / 0.02 reduced albedo).
MATERIALS = ("ketchup", "skin1", "potato", "marble")
BOUNDARIES = ("null", "dielectric")
#: The sphere's radius: many diffusion lengths in every channel of these media, so that the half-space's profile
#: holds and a deviation is a light's mechanism, not the object's shape.
RADIUS_MM = 100.0


def emitter_dict(kind, radius, envmap):
    """A Mitsuba emitter of type ``kind`` lighting a sphere of ``radius`` at the origin from above and in front
    (irradiance about 1 where it faces the light); ``envmap`` is the path of an environment image for ``envmap``."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    position = [3.0 * radius, 6.0 * radius, 4.0 * radius]
    intensity = {"type": "rgb", "value": [50.0 * radius ** 2] * 3}
    return {
        "point": {"type": "point", "position": position, "intensity": intensity},
        "spot": {"type": "spot", "to_world": T().look_at(origin=position, target=[0, 0, 0], up=[0, 1, 0]),
                 "intensity": intensity, "cutoff_angle": 40.0},
        "directional": {"type": "directional", "direction": [-3.0, -6.0, -4.0],
                        "irradiance": {"type": "rgb", "value": [1.0] * 3}},
        # Wide (6 radii across), so that a path tracer finds it through a smooth dielectric often enough.
        "area": {"type": "rectangle", "to_world": T().look_at(origin=[0, 4.0 * radius, 2.0 * radius],
                                                              target=[0, 0, 0], up=[0, 0, 1]).scale(3.0 * radius),
                 "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [0.25] * 3}}},
        "constant": {"type": "constant", "radiance": {"type": "rgb", "value": [0.5] * 3}},
        "envmap": {"type": "envmap", "filename": str(envmap)},
    }[kind]


def write_envmap(path):
    """An 8x16 environment, bright above the horizon and dim below, so that its sampling matters."""
    import mitsuba as mi

    rows = np.where(np.arange(8)[:, None, None] < 4, 1.0, 0.1) * np.ones((8, 16, 3))
    mi.Bitmap(rows.astype(np.float32)).write(str(path))
    return path


#: The environment map of the ``sunmap`` benchmark lighting (:func:`write_sun_sky`).
SUN_SKY = Path(tempfile.gettempdir()) / "convsss-bench-sun-sky.exr"


def write_sun_sky(path=SUN_SKY):
    """A 64x128 environment map of a dim sky (0.3) and a sun of 3x3 pixels (3000) high on its sphere, 90 % of its
    light from 0.1 % of its pixels: light that chance hits through a smooth boundary find rarely. Written once
    (the same bytes every time); returns its path."""
    import mitsuba as mi

    path = Path(path)
    if not path.is_file():
        sky = np.full((64, 128, 3), 0.3, dtype=np.float32)
        sky[10:13, 40:43] = 3000.0
        atomic_write(path, lambda tmp: mi.Bitmap(sky).write(str(tmp)))
    return path


def sphere_dict(material, boundary, emitter, radius=RADIUS_MM, resolution=32, spp=64):
    """The scene: a sphere of ``radius`` mm of the preset ``material`` lit by the ``emitter`` dictionary alone."""
    import mitsuba as mi

    from ..materials import material as preset
    from ..media.dicts import translucent

    T = mi.ScalarTransform4f
    return {
        "type": "scene",
        "integrator": {"type": "convsss", "walk_depth": 0.0},  # the transport's light (walks: bench walk)
        "sensor": {"type": "perspective", "fov": 30,
                   "to_world": T().look_at(origin=[0, 2 * radius, 8 * radius], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": resolution, "height": resolution, "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": spp}},
        "object": translucent({"type": "sphere", "radius": radius}, preset(material, warn=False), boundary=boundary),
        "light": emitter,
    }


@dataclass(frozen=True)
class LightCase:
    """One row: the ratio per channel of convsss's mean to volpathmis's (each the mean of two seeds), and each one's
    noise per channel, ``|mean_seed_a / mean_seed_b - 1|`` (about twice the standard error of the two seeds' mean)."""

    material: str
    boundary: str
    emitter: str
    ratio: tuple
    noise: tuple
    reference_noise: tuple


def cases(materials=MATERIALS, emitters=EMITTERS, boundaries=BOUNDARIES):
    """The ``(material, boundary, emitter)`` of the matrix: dielectric rows only for :data:`AREA_EMITTERS`."""
    return [(m, b, e) for m in materials for b in boundaries for e in emitters
            if b == "null" or e in AREA_EMITTERS]


def light_case(material, boundary, emitter, folder, radius=RADIUS_MM, resolution=32, spp=64, reference_spp=256):
    """One case rendered in this process (convsss seeds 1 and 2, volpathmis 3 and 4): its :class:`LightCase`."""
    from .. import register
    from ..pipeline.reference import reference_integrator, translucent_pixels

    mi = register()
    light = emitter_dict(emitter, radius, write_envmap(folder / "sky.exr"))
    scene = mi.load_dict(sphere_dict(material, boundary, light, radius, resolution, spp))
    # Pixels inside the silhouette (their neighbours' centres hit the sphere too): a pixel the silhouette crosses
    # mixes the background at random, in both renders, and that noise would swamp a dark channel's mean.
    mask = scipy.ndimage.binary_erosion(translucent_pixels(scene))

    def mean(image):
        return np.array(image, dtype=np.float64)[..., :3][mask].mean(axis=0)

    ours = [mean(mi.render(scene, seed=seed)) for seed in (1, 2)]
    volpath = reference_integrator()
    references = [mean(mi.render(scene, integrator=volpath, seed=seed, spp=reference_spp)) for seed in (3, 4)]
    ratio = tuple(float(v) for v in np.mean(ours, axis=0) / np.mean(references, axis=0))
    return LightCase(material, boundary, emitter, ratio,
                     _noise(ours), _noise(references))


def _noise(means):
    """``|a / b - 1|`` per channel of two seeds' means."""
    return tuple(float(v) for v in np.abs(means[0] / means[1] - 1.0))


def bench_lights(materials=MATERIALS, emitters=EMITTERS, boundaries=BOUNDARIES, folder=None, bar=None, **options):
    """:func:`light_case` over :func:`cases`; ``bar`` (a tqdm) is advanced per case."""
    import tempfile
    from pathlib import Path

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for material, boundary, emitter in cases(materials, emitters, boundaries):
            rows.append(light_case(material, boundary, emitter, Path(folder or tmp), **options))
            if bar is not None:
                bar.update()
    return rows


def lights_table(rows):
    """Markdown: one row per case, convsss / volpathmis per channel and the reference's largest noise."""
    lines = ["| material | boundary | emitter | convsss / volpathmis, R / G / B | noise: convsss, volpathmis |",
             "|---|---|---|---|---|"]
    for row in rows:
        ratio = " / ".join(f"{r:.3f}" for r in row.ratio)
        noise = f"{100 * max(row.noise):.1f} %, {100 * max(row.reference_noise):.1f} %"
        lines.append(f"| {row.material} | {row.boundary} | {row.emitter} | {ratio} | {noise} |")
    return "\n".join(lines)
