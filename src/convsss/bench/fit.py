"""Materials from images on ground truth (issue 35): ``convsss fit`` of ``volpathmis`` renders of known materials.

Per case (a preset, or a colour + mean free path; the bundled bunny 20 mm across with a null boundary, under the
quick scene's key and back point lights or under a constant environment): two ``volpathmis`` references (seeds 1
and 2, Russian roulette off; their difference is the reference's own noise), then :func:`convsss.fit.fit` of the
first from a start far off (reduced albedo x 0.7, mean free path x 3), timed. Reported per channel: truth, start,
fitted and their relative errors; the evaluations and seconds; the fitted render's mean against the target's, and
the render at the true material's (convsss's own bias), so that a fitted material that differs from the truth by
the model's bias reads as such.
"""

import time

import numpy as np
from tqdm import tqdm

from .scenes import bench_material

#: The materials: a name, a preset's name or a colour (the exact total reflectance) and a mean free path (mm).
MATERIALS = (("milk", "wholemilk"), ("marble", "marble"), ("skin1", "skin1"), ("ketchup", "ketchup"),
             ("potato", "potato"), ("orange", ((0.7, 0.5, 0.3), 1.5)), ("jade", ((0.4, 0.6, 0.8), 4.0)))
#: The cases: a name, the material, the light; every material under the point lights, then under the environment.
CASES = tuple((name, spec, "points") for name, spec in MATERIALS) + tuple(
    (f"{name}-env", spec, "environment") for name, spec in MATERIALS)


def _scene(mi, material, light, width):
    from ..scene.quick import demo_mesh, quick_scene

    scene = quick_scene(demo_mesh(), material, 20.0, width=width, height=width, spp=4, boundary="null",
                        integrator={"type": "convsss"})
    if light == "environment":
        scene = {k: v for k, v in scene.items() if not (isinstance(v, dict) and v.get("type") == "point")}
        scene["sky"] = {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}}
    return mi.load_dict(scene)


def bench_fit(cases=CASES, width=128, reference_spp=1024, spp=None, progress=True):
    """Rows, one per case: ``name``, ``light``, per channel ``truth``, ``start``, ``fitted`` (``albedo`` and
    ``mfp_mm`` each), ``error`` and ``std`` (the fit's own standard deviations; both relative), ``evaluations``,
    ``seconds``, ``reference_noise`` (relative RMS of the two references' difference / sqrt 2), ``fitted_ratio``
    and ``truth_ratio`` (mean render / mean target)."""
    import convsss

    from ..fitting import WALK_SPP, fit, material_of
    from ..pipeline.reference import render_reference

    mi = convsss.register()
    rows = []
    bar = tqdm(total=len(cases), desc="bench fit", unit="case", disable=not progress)
    for name, spec, light in cases:
        truth = bench_material(spec)
        truth = material_of(truth.albedo_prime, truth.mfp_mm, 1.0, truth.name)  # the null boundary's eta
        refs = [render_reference(_scene(mi, truth, light, width), reference_spp, 32, seed) for seed in (1, 2)]
        start = material_of(np.clip(truth.albedo_prime * 0.7, 1e-3, 0.999), truth.mfp_mm * 3.0, 1.0)
        begun = time.perf_counter()
        # The scene holds the start, as a user's would: the truth reaches the fit through the target alone (the
        # plan's sample spacing and the paths' choices come from the scene's material).
        result = fit(_scene(mi, start, light, width), refs[0], start=start, spp=spp, max_evaluations=100)
        seconds = time.perf_counter() - begun
        inside = result.mask
        target = refs[0][inside]
        noise = np.sqrt(np.mean(((refs[0] - refs[1])[inside] / np.sqrt(2)) ** 2, axis=0)) / target.mean(axis=0)
        at_truth = np.array(convsss.render(_scene(mi, truth, light, width), seed=0, spp=spp or WALK_SPP))
        at_truth = at_truth[..., :3][inside]
        rows.append({"name": name, "light": light, "width": width,
                     "truth": {"albedo": truth.albedo_prime.tolist(), "mfp_mm": truth.mfp_mm.tolist()},
                     "start": {"albedo": start.albedo_prime.tolist(), "mfp_mm": start.mfp_mm.tolist()},
                     "fitted": {"albedo": result.reduced_albedo.tolist(), "mfp_mm": result.mfp_mm.tolist()},
                     "error": {"albedo": (result.reduced_albedo / truth.albedo_prime - 1).tolist(),
                               "mfp_mm": (result.mfp_mm / truth.mfp_mm - 1).tolist()},
                     "std": {"albedo": (result.reduced_albedo_std / result.reduced_albedo).tolist(),
                             "mfp_mm": (result.mfp_mm_std / result.mfp_mm).tolist()},
                     "evaluations": result.evaluations, "seconds": seconds, "reference_noise": noise.tolist(),
                     "fitted_ratio": (result.render[inside].mean(axis=0) / target.mean(axis=0)).tolist(),
                     "truth_ratio": (at_truth.mean(axis=0) / target.mean(axis=0)).tolist()})
        bar.update()
    bar.close()
    return rows


def fit_table(rows):
    """A Markdown table of :func:`bench_fit`'s rows (per channel R/G/B)."""

    def rgb(values, digits=3):
        return "/".join(f"{v:.{digits}f}" for v in values)

    def pct(values):
        return "/".join(f"{100 * v:+.1f}" for v in values)

    lines = ["| case | light | truth albedo; mfp mm | fitted albedo; mfp mm | error albedo; mfp (%) | renders | s | "
             "fit's std albedo; mfp (%) | fitted / target | truth / target | ref. noise (%) |", "|" + "---|" * 11]
    for r in rows:
        lines.append(f"| {r['name']} | {r['light']} | {rgb(r['truth']['albedo'])}; {rgb(r['truth']['mfp_mm'])} | "
                     f"{rgb(r['fitted']['albedo'])}; {rgb(r['fitted']['mfp_mm'])} | {pct(r['error']['albedo'])}; "
                     f"{pct(r['error']['mfp_mm'])} | {r['evaluations']} | {r['seconds']:.0f} | "
                     f"{rgb([100 * v for v in r['std']['albedo']], 1)}; "
                     f"{rgb([100 * v for v in r['std']['mfp_mm']], 1)} | "
                     f"{rgb(r['fitted_ratio'])} | {rgb(r['truth_ratio'])} | "
                     f"{rgb([100 * v for v in r['reference_noise']], 2)} |")
    return "\n".join(lines)
