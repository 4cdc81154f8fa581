"""The render matrix of the reliability battery (issue 9): every emitter type x boundary x transport on a tiny scene,
each render ending in a finite, non-negative image with the sphere lit.

The scene: a 1 mm whole-milk sphere above a floor, 16x16 pixels, 1 spp, a box filter, one emitter of each Mitsuba
type as :func:`~convsss.bench.lights.emitter_dict` places it. ``convsss bench battery`` renders the whole matrix;
the test suite renders the cases of :func:`pairwise` (every boundary with every transport, the emitters taken in
turn) and random parameters on the same scene.

    convsss bench battery [--json]
"""

import itertools
import time
from dataclasses import dataclass

import numpy as np

from ..media.dicts import BOUNDARIES, translucent
from ..pipeline.params import available_transports
from .lights import EMITTERS, emitter_dict

#: The tiny scene's film side in pixels.
SIZE = 16


def tiny_scene(mi, envmap, emitter="point", boundary="null", integrator=None, material="wholemilk"):
    """The loaded tiny scene (module doc) lit by one ``emitter`` (``envmap``: the environment image's path)."""
    from .. import material as preset

    T = mi.ScalarTransform4f
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "convsss", "sample_density": 1.0, "irradiance_samples": 4, "walk_depth": 0.0,
                       **(integrator or {})},
        "sensor": {"type": "perspective", "fov": 35,
                   "to_world": T().look_at(origin=[0, 1, 5], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE, "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": 1}},
        "object": translucent({"type": "sphere"}, preset(material), boundary=boundary),
        "floor": {"type": "rectangle", "to_world": T().translate([0, -1, 0]).rotate([1, 0, 0], -90).scale(10)},
        "light": emitter_dict(emitter, 1.0, envmap),
    })


def render_tiny(scene):
    """The tiny scene's RGB (float64), seed 1."""
    image = np.array(scene.integrator().render(scene, scene.sensors()[0], seed=1), dtype=np.float64)
    return image[..., :3]


def matrix():
    """Every ``(emitter, boundary, transport)``."""
    return list(itertools.product(EMITTERS, BOUNDARIES, available_transports()))


def pairwise():
    """Every boundary with every transport, the emitters taken in turn (each at least twice): a covering subset of
    :func:`matrix`, every factor and every boundary-transport pair in it."""
    pairs = list(itertools.product(BOUNDARIES, available_transports()))
    return [(EMITTERS[k % len(EMITTERS)], boundary, transport) for k, (boundary, transport) in enumerate(pairs)]


@dataclass(frozen=True)
class BatteryCase:
    """One render of the matrix: whether its image is ``finite``, ``non_negative`` and shows the sphere ``lit``
    (the middle of the frame brighter than 0), and its ``seconds``."""

    emitter: str
    boundary: str
    transport: str
    finite: bool
    non_negative: bool
    lit: bool
    seconds: float

    @property
    def ok(self):
        return self.finite and self.non_negative and self.lit


def run_case(mi, envmap, emitter, boundary, transport):
    """One case of the matrix rendered in this process: its :class:`BatteryCase`."""
    start = time.perf_counter()
    image = render_tiny(tiny_scene(mi, envmap, emitter, boundary, {"transport": transport}))
    middle = slice(SIZE // 2 - 2, SIZE // 2 + 2)
    return BatteryCase(emitter, boundary, transport, bool(np.all(np.isfinite(image))),
                       bool(np.nanmin(image) >= 0), bool(image[middle, middle].mean() > 0),
                       time.perf_counter() - start)


def bench_battery(cases=None, bar=None):
    """:func:`run_case` over ``cases`` (default: the whole :func:`matrix`); ``bar`` (a tqdm) is advanced per case."""
    import tempfile
    from pathlib import Path

    from .. import register
    from .lights import write_envmap

    mi = register()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        envmap = write_envmap(Path(tmp) / "sky.exr")
        for case in matrix() if cases is None else cases:
            rows.append(run_case(mi, envmap, *case))
            if bar is not None:
                bar.update()
    return rows


def battery_table(rows):
    """Markdown: one row per case, and the count of cases that ended well."""
    lines = ["| emitter | boundary | transport | finite | non-negative | lit | seconds |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r.emitter} | {r.boundary} | {r.transport} | {'yes' if r.finite else 'NO'} | "
                     f"{'yes' if r.non_negative else 'NO'} | {'yes' if r.lit else 'NO'} | {r.seconds:.2f} |")
    lines.append(f"\n{sum(r.ok for r in rows)} of {len(rows)} cases finite, non-negative and lit.")
    return "\n".join(lines)
