"""How deep a walk should go: bias and cost of ``walk_depth`` against path tracing, per scene.

Per scene (the families where diffusion fails: back light, thin limbs behind a dielectric, an object a few mean
free paths across, low albedo; and one where it holds), as whole commands in fresh processes on one scene file:

1. two references, ``convsss reference --spp REFERENCE_SPP`` with seeds 1 and 2 (their own noise: half the relative
   MSE between them);
2. ``convsss render --walk-depth D --spp SPP`` for each depth ``D`` (0: the transport alone; inf: every walk to its
   end), and ``convsss reference --spp SPP`` (volpathmis at the same samples per pixel).

Each row holds the mean over the object's pixels against the first reference's per channel (the bias, with the
references' own ratio beside it), the relative MSE less the reference's noise, the seconds of the command and, for
the walk, the mean scattering events per path and the share of paths ended in the diffusion field.
"""

import math
import os
import tempfile
from pathlib import Path

import numpy as np
from tqdm import tqdm

from .scenes import BenchScene
from .volpath import _image, _run, relative_mse, two_references

#: The benchmark's scenes: skin lit from behind, thin limbs behind a dielectric under an area light, milk a few
#: mean free paths across, ketchup (low albedo in green and blue), marble behind a dielectric (diffusion holds); and
#: the rest of issue 50's: a long-mfp medium behind a rough dielectric under a sun and a sky (skim milk), thin wings
#: behind glass under a side light (a jade colour on Lucy), potato behind a dielectric under an environment; and issue
#: 60's: the potato under an environment map with a small sun, and a large marble object (diffusion holds) beside a
#: small skin one (it fails), each rendered its own way.
WALK_SCENES = {
    "skin40-back": BenchScene("bunny", "skin1", 40.0, "back"),
    "armadillo30-area": BenchScene("armadillo.obj", "skin1", 30.0, "area"),
    "milk4": BenchScene("bunny", "wholemilk", 4.0),
    "ketchup20": BenchScene("bunny", "ketchup", 20.0),
    "marble40-area": BenchScene("bunny", "marble", 40.0, "area"),
    "dragon40-sun": BenchScene("dragon.ply", "skimmilk", 40.0, "sun"),
    "lucy40-side": BenchScene("lucy.obj", ((0.4, 0.6, 0.8), 4.0), 40.0, "side"),
    "potato40-env": BenchScene("bunny", "potato", 40.0, "environment"),
    "potato40-map": BenchScene("bunny", "potato", 40.0, "sunmap"),
    "marble40+skin10": BenchScene("bunny", "marble", 40.0, "area", companion=("skin1", 10.0)),
}
DEPTHS = (0.0, 2.0, 4.0, 8.0, 16.0, math.inf)
REFERENCE_SPP = 1024
SPP = 64


def _label(depth):
    """A walk depth as the command line takes it: ``4``, ``inf``, ``auto``."""
    return depth if isinstance(depth, str) else f"{depth:g}"


def _mean_ratio(reference, test, mask):
    inside = mask > 0.5
    return (test[inside].mean(axis=0) / np.maximum(reference[inside].mean(axis=0), 1e-30)).tolist()


def bench_walk_scene(name, scene, width, folder, spp=SPP, reference_spp=REFERENCE_SPP, depths=DEPTHS, bar=None):
    """One scene's rows (module doc): ``{scene, reference_s, reference_noise, reference_ratio, rows: [...]}``."""
    import json

    from ..scene.xmlwriter import scene_to_xml
    from .scenes import scene_dict

    folder = Path(folder)
    path = folder / f"{name}-{width}.xml"
    path.write_text(scene_to_xml(scene_dict(scene, width)))

    def step(label):
        if bar is not None:
            bar.set_postfix_str(f"{name} {label}")

    seconds = two_references(path, folder, reference_spp, step, bar)
    reference, second = _image(folder / "ref1.exr")[0], _image(folder / "ref2.exr")[0]
    rows = []
    mask = None
    for depth in depths:
        label = _label(depth)
        step(f"walk_depth {label}")
        out = folder / f"walk-{label}"
        took = _run(["render", str(path), "-o", str(out), "--walk-depth", label, "--spp", str(spp),
                     "--aovs", "mask", "--stats", str(out.with_suffix(".json")), "--seed", "3"])
        image, mask = _image(out.with_suffix(".exr"))
        stats = json.loads(out.with_suffix(".json").read_text())
        walk = stats.get("walk", {})
        rows.append({"walk_depth": depth, "rendered": stats.get("walk_depth"), "seconds": took,
                     "stage_seconds": stats["seconds"],
                     "ratio": _mean_ratio(reference, image, mask), "error": relative_mse(reference, image, mask),
                     "events_per_path": walk.get("events_per_path"), "ended_share": walk.get("ended_share")})
        if bar is not None:
            bar.update()
    noise = 0.5 * relative_mse(reference, second, mask)
    step("volpathmis")
    took = _run(["reference", str(path), "-o", str(folder / "volpath"), "--spp", str(spp), "--seed", "3"])
    image = _image(folder / "volpath.exr")[0]
    rows.append({"walk_depth": "volpathmis", "seconds": took, "ratio": _mean_ratio(reference, image, mask),
                 "error": relative_mse(reference, image, mask)})
    if bar is not None:
        bar.update()
    for row in rows:
        row["error"] -= noise
    return {"scene": name, "reference_s": float(np.median(seconds)), "reference_noise": noise,
            "reference_ratio": _mean_ratio(reference, second, mask), "rows": rows}


def bench_walk(scenes=tuple(WALK_SCENES), width=64, spp=SPP, reference_spp=REFERENCE_SPP, depths=DEPTHS,
               progress=True):
    """:func:`bench_walk_scene` for every scene: ``{meta, scenes}``."""
    bar = tqdm(total=len(scenes) * (3 + len(depths)), desc="bench walk", unit="command", disable=not progress)
    meta = {"width": width, "spp": spp, "reference_spp": reference_spp, "depths": [_label(d) for d in depths],
            "cpus": os.cpu_count(), "load_average_start": list(os.getloadavg())}
    out = []
    with tempfile.TemporaryDirectory() as folder:
        for name in scenes:
            out.append(bench_walk_scene(name, WALK_SCENES[name], width, folder, spp, reference_spp, depths, bar))
    bar.close()
    meta["load_average_end"] = list(os.getloadavg())
    return {"meta": meta, "scenes": out}


def walk_table(result):
    """The rows as a text table: per scene and depth, the mean against the reference (R/G/B), the relative MSE
    less the reference's noise, seconds, events per path and the share ended in the field."""
    lines = [f"{'scene':>18} {'walk_depth':>10} {'mean/ref R/G/B':>20} {'relMSE':>9} {'seconds':>8} "
             f"{'events/path':>11} {'ended':>6}"]
    for s in result["scenes"]:
        ratio = "/".join(f"{x:.3f}" for x in s["reference_ratio"])
        lines.append(f"{s['scene']:>18} {'reference':>10} {ratio:>20} {s['reference_noise']:>9.2e} "
                     f"{s['reference_s']:>8.1f}")
        for r in s["rows"]:
            depth = _label(r["walk_depth"])
            if r.get("rendered") not in (None, depth):
                depth = f"{depth}={r['rendered']}"
            ratio = "/".join(f"{x:.3f}" for x in r["ratio"])
            events = "" if r.get("events_per_path") is None else f"{r['events_per_path']:.2f}"
            ended = "" if r.get("ended_share") is None else f"{r['ended_share']:.3f}"
            lines.append(f"{'':>18} {depth:>10} {ratio:>20} {r['error']:>9.2e} {r['seconds']:>8.1f} {events:>11} "
                         f"{ended:>6}")
    return "\n".join(lines)


def walk_plot(result, path):
    """Bias (the worst channel's |mean/ref - 1|) and seconds against ``walk_depth``, a panel each, a line per scene;
    volpathmis at the same spp as a marker at the right. Written to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    depths = [d for d in result["meta"]["depths"]]
    x = np.arange(len(depths) + 1)
    fig, (bias, cost) = plt.subplots(1, 2, figsize=(10, 4))
    for s in result["scenes"]:
        worst = [max(abs(v - 1.0) for v in r["ratio"]) for r in s["rows"]]
        seconds = [r["seconds"] for r in s["rows"]]
        line = bias.plot(x[:-1], worst[:-1], marker="o", label=s["scene"])[0]
        bias.plot(x[-1], worst[-1], marker="s", color=line.get_color())
        cost.plot(x[:-1], seconds[:-1], marker="o", color=line.get_color())
        cost.plot(x[-1], seconds[-1], marker="s", color=line.get_color())
    labels = [*depths, "volpathmis"]
    for ax, title in ((bias, "worst channel |mean / reference - 1|"), (cost, "seconds (fresh process)")):
        ax.set_xticks(x, labels)
        ax.set_xlabel("walk_depth (transport mean free paths)")
        ax.set_title(title)
        ax.set_yscale("log")
        ax.grid(True, alpha=0.3)
    bias.legend(fontsize=8)
    meta = result["meta"]
    fig.suptitle(f"{meta['width']}x{meta['width']}, {meta['spp']} spp; references {meta['reference_spp']} spp")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
