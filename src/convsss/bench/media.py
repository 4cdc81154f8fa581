"""Heterogeneous interiors against path tracing: veined marble, a medium fading from milk to skin, two layers.

Per scene, everything as whole commands in fresh processes on one scene file (Mitsuba XML with ``gridvolume``
volumes, written here):

1. two references, ``convsss reference --spp REFERENCE_SPP`` with seeds 1 and 2 (kept in the output folder and reused
   when it already holds them complete at that spp and size);
2. ``convsss render`` of the scene and of its **homogeneous twin** (the same object, camera and lights with one
   homogeneous medium), ``runs`` times each, interleaved: the medians, and their ratio (the issue's cost goal);
3. errors over the object's pixels (the render's mask AOV) against the first reference with
   :func:`convsss.compare.metrics`: per channel the ratio of the means, the mean relative error beside the second
   reference's (the reference's own noise in the same metric), and the relative MSE less the reference's own noise
   (half the relative MSE between the two references) beside that noise;
4. the twin's render against the twin's own reference (seed 1): its ratio of the means is what the homogeneous
   model gets wrong on that shape and light, and the scene's ratio over the twin's (``medium_ratio``) what the
   medium's variation adds.

Scenes (null boundary, the key and back point lights of :func:`~convsss.scene.quick.quick_scene`):

- ``veins-block``: a 30 x 20 x 20 mm block of marble with dark veins (a 64^3 albedo ``gridvolume``: sheets about
  1 mm thick, 7 mm apart, albedo 0.9/0.85/0.8 against marble's 0.999); twin: marble;
- ``veins-bunny``: the same veins through a 20 mm bunny; twin: marble;
- ``milk-skin-sphere``: a 20 mm sphere whose coefficients go linearly from whole milk (left) to skin1 (right) (albedo
  and ``sigma_t`` volumes); twin: the half-and-half mixture, homogeneous;
- ``skin-over-milk``: a 20 mm sphere, 1.5 mm of skin1 over a whole-milk core; twin: skin1;
- ``textured-bunny``: a 20 mm bunny whose ``convsss_medium`` colour is a painted map (:func:`painted_texture`:
  skin-like, with darker patches 7 mm across) at a mean free path of 0.5 mm, on texture coordinates projected along
  the view (:func:`_uv_mesh`); its reference renders the heterogeneous medium the texture stands for
  (:mod:`convsss.scene.textures`); twin: the homogeneous medium of the map's mean colour;
- ``constant-block``: the block with a constant albedo volume of marble's albedo: its render against the twin's,
  pixel for pixel (no reference).
"""

import os
import statistics
import tempfile
from pathlib import Path

import numpy as np
from tqdm import tqdm

from .volpath import _image, _run

MEDIA_SCENES = ("veins-block", "veins-bunny", "milk-skin-sphere", "skin-over-milk", "textured-bunny", "constant-block")
REFERENCE_SPP = 512
#: Albedo of the veins' darkest cells, per channel.
VEIN_ALBEDO = (0.9, 0.85, 0.8)


def _box_obj(path, sides):
    """A closed box mesh of ``sides`` (3,) centred on the origin, faces wound outwards, as OBJ."""
    x, y, z = (0.5 * float(s) for s in sides)
    corners = [(sx * x, sy * y, sz * z) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    lines = [f"v {a} {b} {c}" for a, b, c in corners]
    lines += [f"f {a} {b} {c}\nf {a} {c} {d}" for a, b, c, d in faces]
    Path(path).write_text("\n".join(lines) + "\n")
    return path


def _uv_mesh(mi, mesh, path):
    """``mesh`` written to ``path`` (PLY) with texture coordinates projected along z: ``(u, v)`` its (x, y) over
    its bounding box (no seam)."""
    from ..scene.quick import load_mesh

    params = mi.traverse(load_mesh(mesh))
    positions = np.asarray(params["vertex_positions"], dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(params["faces"], dtype=np.uint32)
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    uv = (positions[:, :2] - lo[:2]) / (hi[:2] - lo[:2])
    out = mi.Mesh("uv", len(positions), len(faces) // 3, has_vertex_texcoords=True)
    params = mi.traverse(out)
    params["vertex_positions"] = mi.Float(positions.astype(np.float32).ravel())
    params["faces"] = mi.UInt32(faces)
    params["vertex_texcoords"] = mi.Float(uv.astype(np.float32).ravel())
    params.update()
    out.write_ply(str(path))
    return Path(path)


def painted_texture(mi, path, size=256):
    """A colour map written to ``path`` (EXR, linear): a skin-like colour with darker patches, 3 x 2 across."""
    v, u = np.meshgrid((np.arange(size) + 0.5) / size, (np.arange(size) + 0.5) / size, indexing="ij")
    patches = (0.5 + 0.5 * np.sin(2 * np.pi * 3 * u) * np.sin(2 * np.pi * 2 * v))[..., None] ** 2
    color = (1 - patches) * np.array([0.75, 0.55, 0.45]) + patches * np.array([0.25, 0.1, 0.06])
    mi.Bitmap(color.astype(np.float32)).write(str(path))
    return color


def _grid(mi, path, values):
    mi.VolumeGrid(np.ascontiguousarray(values, dtype=np.float32)).write(str(path))
    return str(path)


def vein_albedo(base_albedo, n=64):
    """(n, n, n, 3) albedo cells (z, y, x) of ``base_albedo`` crossed by dark sinuous sheets (:data:`VEIN_ALBEDO`)."""
    z, y, x = np.meshgrid(*[np.linspace(0.0, 1.0, n)] * 3, indexing="ij")
    phase = np.sin(9 * x + 3 * np.sin(6 * y) + 2 * np.sin(5 * z))
    vein = np.exp(-(phase / 0.25) ** 2)[..., None]
    return np.asarray(base_albedo) * (1 - vein) + np.asarray(VEIN_ALBEDO) * vein


def _sphere_object(scene, interior, radius):
    """``scene``'s object replaced by a sphere of ``radius`` standing on y = 0 with ``interior``."""
    scene["object"] = {"type": "sphere", "center": [0.0, radius, 0.0], "radius": radius,
                       "bsdf": {"type": "null"}, "interior": interior}
    return scene


def _graded_medium(mi, folder, name, fraction, box, material_a, material_b, n=48):
    """A heterogeneous medium of ``material_a`` where ``fraction`` (a function of the cell centres' (z, y, x) in
    [0, 1]) is 0 and ``material_b`` where it is 1, the reduced coefficients mixed linearly, over the box ``box``
    (its to_world)."""
    axes = (np.arange(n) + 0.5) / n
    t = fraction(*np.meshgrid(axes, axes, axes, indexing="ij"))[..., None]
    sigma_s = (1 - t) * material_a.sigma_s_prime + t * material_b.sigma_s_prime
    sigma_t = sigma_s + (1 - t) * material_a.sigma_a + t * material_b.sigma_a
    scale = float(sigma_t.max())
    return {"type": "heterogeneous", "scale": scale,
            "albedo": {"type": "gridvolume", "filename": _grid(mi, folder / f"{name}-albedo.vol", sigma_s / sigma_t),
                       "to_world": box},
            "sigma_t": {"type": "gridvolume", "filename": _grid(mi, folder / f"{name}-sigma_t.vol", sigma_t / scale),
                        "to_world": box}}


def scene_pair(name, width, folder):
    """``(scene, twin)``: the scene dictionaries of ``name`` (:data:`MEDIA_SCENES`) at ``width``² and of its
    homogeneous twin; volume and mesh files are written to ``folder``."""
    from .. import material
    from ..backend import load_mitsuba
    from ..materials import Material
    from ..media.dicts import medium_parameters, translucent
    from ..scene.quick import demo_mesh, quick_scene

    mi = load_mitsuba()
    folder = Path(folder)
    marble, milk, skin = material("marble"), material("wholemilk"), material("skin1")
    base = medium_parameters(marble)["albedo"]

    def quick(mesh, made, size, volume=None):
        return quick_scene(mesh, made, size, width, width, 16, False, "null", albedo_volume=volume)

    if name in ("veins-block", "constant-block", "veins-bunny"):
        mesh = demo_mesh() if name == "veins-bunny" else _box_obj(folder / "block.obj", (1.5, 1.0, 1.0))
        size = 20.0 if name == "veins-bunny" else 30.0
        cells = vein_albedo(base) if name.startswith("veins") else np.broadcast_to(base.astype(np.float32),
                                                                                   (8, 8, 8, 3))
        volume = _grid(mi, folder / f"{name}.vol", cells)
        return quick(mesh, marble, size, volume), quick(mesh, marble, size)
    if name == "textured-bunny":
        from ..profiles.models import material_from_color
        from ..scene.quick import color_texture_medium

        mesh = _uv_mesh(mi, demo_mesh(), folder / "bunny-uv.ply")
        color = painted_texture(mi, folder / "painted.exr")
        mfp = 0.5
        twin_material = material_from_color(color.reshape(-1, 3).mean(axis=0), mfp, 1.0, name="painted mean")
        scene, twin = quick(mesh, twin_material, 20.0), quick(mesh, twin_material, 20.0)
        scene["object"]["interior"] = color_texture_medium(twin_material, folder / "painted.exr", mfp, "exact")
        return scene, twin
    radius = 10.0
    box = mi.ScalarTransform4f().translate([-1.02 * radius, -0.02 * radius, -1.02 * radius]).scale(2.04 * radius)
    if name == "milk-skin-sphere":
        interior = _graded_medium(mi, folder, name, lambda z, y, x: x, box, milk, skin)
        twin_material = Material(0.5 * (milk.sigma_s_prime + skin.sigma_s_prime), 0.5 * (milk.sigma_a + skin.sigma_a),
                                 1.0, "milk-skin")
    elif name == "skin-over-milk":
        shell = 1.5 / (2.04 * radius)  # in the box's unit coordinates

        def outer(z, y, x):
            r = np.sqrt((x - 0.5) ** 2 + (y - 0.5) ** 2 + (z - 0.5) ** 2)
            return (r > 0.5 / 1.02 - shell).astype(float)

        interior = _graded_medium(mi, folder, name, outer, box, milk, skin, n=96)
        twin_material = skin
    else:
        raise ValueError(f"unknown media scene {name!r}")
    mesh = _box_obj(folder / "cube.obj", (1.0, 1.0, 1.0))
    scene, twin = quick(mesh, skin, 2 * radius), quick(mesh, skin, 2 * radius)
    twin_object = translucent({"type": "sphere"}, twin_material, boundary="null")
    return _sphere_object(scene, interior, radius), _sphere_object(twin, twin_object["interior"], radius)


def bench_media_scene(name, width, folder, reference_spp=REFERENCE_SPP, runs=3, bar=None):
    """One row (module docstring): ``{scene, width, classes, samples, walk_depth, convsss_s, twin_s, cost_ratio,
    mean_ratio, twin_mean_ratio, medium_ratio, mean_rel_error, reference_mean_rel_error, relmse_excess,
    reference_noise}``, or for ``constant-block`` ``{..., identical, max_rel_difference}``."""
    import json

    from ..compare import metrics, prepare
    from ..scene.xmlwriter import scene_to_xml

    folder = Path(folder)
    scene, twin = scene_pair(name, width, folder)
    files = {"scene": folder / f"{name}-{width}.xml", "twin": folder / f"{name}-{width}-twin.xml"}
    for key, value in (("scene", scene), ("twin", twin)):
        files[key].write_text(scene_to_xml(value))

    def tick(label):
        if bar is not None:
            bar.set_postfix_str(f"{name} {label}")
            bar.update()

    seconds = {"scene": [], "twin": []}
    for _ in range(runs):
        for key in ("scene", "twin"):
            seconds[key].append(_run(["render", str(files[key]), "-o", str(folder / f"{name}-{width}-{key}"),
                                      "--aovs", "mask", "--stats", str(folder / f"{name}-{width}-{key}.json")]))
            tick(f"render {key}")
    test, mask = _image(folder / f"{name}-{width}-scene.exr")
    stats = json.loads((folder / f"{name}-{width}-scene.json").read_text())
    # What the default rendered (walks draw no surface samples), and the object's classes (its survey's).
    row = {"scene": name, "width": width, "classes": stats["objects"][0]["classes"], "samples": stats["samples"],
           "walk_depth": stats["walk_depth"], "convsss_s": statistics.median(seconds["scene"]),
           "twin_s": statistics.median(seconds["twin"])}
    row["cost_ratio"] = row["convsss_s"] / row["twin_s"]
    if name == "constant-block":
        twin_image = _image(folder / f"{name}-{width}-twin.exr")[0]
        row["identical"] = bool(np.array_equal(test, twin_image))
        row["max_rel_difference"] = float(np.abs(test - twin_image).max() / max(twin_image.max(), 1e-300))
        return row
    def reference(key, seed):
        path = folder / f"ref-{name}-{width}-{reference_spp}-s{seed}{'-twin' if key == 'twin' else ''}.exr"
        done = path.with_suffix(".json")
        if not (path.exists() and done.exists() and json.loads(done.read_text()).get("spp_done") == reference_spp):
            _run(["reference", str(files[key]), "-o", str(path.with_suffix("")), "--spp", str(reference_spp),
                  "--seed", str(seed)])
        tick(f"reference {key} seed {seed}")
        return _image(path)[0]

    references = [reference("scene", seed) for seed in (1, 2)]
    a, b, inside = prepare(references[0], test, mask)
    own = metrics(*prepare(references[0], references[1], mask)[:2], inside)
    found = metrics(a, b, inside)
    twin_test, twin_mask = _image(folder / f"{name}-{width}-twin.exr")
    twin = metrics(*prepare(reference("twin", 1), twin_test, twin_mask))
    noise = 0.5 * own["relmse"]
    row.update({"mean_ratio": found["mean_ratio"].tolist(), "twin_mean_ratio": twin["mean_ratio"].tolist(),
                "medium_ratio": (found["mean_ratio"] / twin["mean_ratio"]).tolist(),
                "mean_rel_error": found["mean_rel_error"].tolist(),
                "reference_mean_rel_error": own["mean_rel_error"].tolist(),
                "relmse_excess": (found["relmse"] - noise).tolist(), "reference_noise": noise.tolist()})
    return row


def bench_media(scenes=MEDIA_SCENES, width=128, reference_spp=REFERENCE_SPP, runs=3, folder=None, progress=True):
    """The rows of :func:`bench_media_scene` and the machine's facts: ``{meta, rows}``; files in ``folder`` (kept, and
    its references reused) or a temporary one."""
    bar = tqdm(total=sum(2 * runs + (0 if s == "constant-block" else 3) for s in scenes), desc="bench media",
               unit="command", disable=not progress)
    meta = {"reference_spp": reference_spp, "width": width, "runs": runs, "cpus": os.cpu_count(),
            "load_average_start": list(os.getloadavg())}
    with tempfile.TemporaryDirectory() as temporary:
        where = Path(folder or temporary)
        where.mkdir(parents=True, exist_ok=True)
        rows = [bench_media_scene(name, width, where, reference_spp, runs, bar) for name in scenes]
    bar.close()
    meta["load_average_end"] = list(os.getloadavg())
    return {"meta": meta, "rows": rows}


def media_table(result):
    """The rows as text: cost against the twin, per channel mean ratio, mean relative error beside the reference's."""
    def rgb(values, digits=3):
        return "/".join(f"{v:.{digits}f}" for v in values)

    lines = [f"{'scene':>17} {'classes':>7} {'walk':>4} {'samples':>8} {'convsss s':>9} {'twin s':>6} {'cost':>5} "
             f"{'mean ratio R/G/B':>17} {'twin ratio':>17} {'medium ratio':>17} {'mean rel err':>17} "
             f"{'ref own':>17} {'relMSE excess':>20} {'ref noise':>20}"]
    for r in result["rows"]:
        head = (f"{r['scene']:>17} {r['classes']:>7} {r['walk_depth']:>4} {r['samples']:>8} {r['convsss_s']:>9.2f} "
                f"{r['twin_s']:>6.2f} {r['cost_ratio']:>5.2f}")
        if "identical" in r:
            lines.append(f"{head}  renders as the twin: {'bit for bit' if r['identical'] else 'no'} "
                         f"(largest difference {r['max_rel_difference']:.2g} of the peak)")
            continue
        lines.append(f"{head} {rgb(r['mean_ratio']):>17} {rgb(r['twin_mean_ratio']):>17} "
                     f"{rgb(r['medium_ratio']):>17} {rgb(r['mean_rel_error']):>17} "
                     f"{rgb(r['reference_mean_rel_error']):>17} {rgb(r['relmse_excess'], 4):>20} "
                     f"{rgb(r['reference_noise'], 4):>20}")
    meta = result["meta"]
    lines.append(f"{meta['width']}², references {meta['reference_spp']} spp (seeds 1, 2), medians of {meta['runs']} "
                 f"fresh commands; {meta['cpus']} CPUs, load {meta['load_average_start'][0]:.2f} -> "
                 f"{meta['load_average_end'][0]:.2f}")
    return "\n".join(lines)
