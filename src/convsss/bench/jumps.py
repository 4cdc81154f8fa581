"""Jumps across the deep interior (issue 60, item 4): what they save where the default walks.

Per scene (a ``bench walk`` or ``bench volpath`` scene, or ``MATERIAL:DIAMETER_MM:LIGHTING`` for a bunny of
:class:`~.scenes.BenchScene`), in one process, the default render with the parameter ``jumps`` off and on: the
shading stage's seconds (median of ``runs`` renders of new seeds after one untimed, the kernels compiled), the walk's
scattering events and jumps per path, and the image's mean over the object per channel with jumps over without (the
same seeds). ``--force-walks``
renders walks where ``auto`` keeps the transport (the diffusion rule's span set beyond every object: a measurement
of the walks themselves on large objects, not what the default renders).

    python -m convsss.bench.jumps [--width W] [--spp S] [--runs N] [--force-walks] SCENE...
"""

import argparse
import statistics


def bench_jumps(names, width=64, spp=64, runs=5, force_walks=False):
    """One row per scene: ``{scene, seconds: {off, on}, events: {off, on}, jumps, mean_ratio}``."""
    import numpy as np

    import convsss
    from convsss.pipeline import objects
    from convsss.pipeline.reference import translucent_pixels

    from .scenes import BenchScene, scene_dict
    from .volpath import VOLPATH_SCENES
    from .walk import WALK_SCENES

    mi = convsss.register()
    span = objects.DIFFUSION_SPAN
    objects.DIFFUSION_SPAN = float("inf") if force_walks else span
    rows = []
    try:
        for name in names:
            if name in WALK_SCENES or name in VOLPATH_SCENES:
                spec = {**VOLPATH_SCENES, **WALK_SCENES}[name]
            else:
                material, diameter, lighting = name.split(":")
                spec = BenchScene("bunny", material, float(diameter), lighting)
            scene_spec = scene_dict(spec, width)
            scene_spec.pop("integrator")
            scene = mi.load_dict(scene_spec)
            inside = translucent_pixels(scene)
            row = {"scene": name, "seconds": {}, "events": {}, "means": {}}
            for jumps in ("off", "on"):
                integrator = mi.load_dict({"type": "convsss", "jumps": jumps})
                mi.render(scene, integrator=integrator, spp=spp, seed=0)
                seconds, means = [], []
                for seed in range(1, runs + 1):
                    image = np.array(mi.render(scene, integrator=integrator, spp=spp, seed=seed))[..., :3]
                    seconds.append(integrator.stats["seconds"]["shading"])
                    means.append(image[inside].mean(axis=0))
                walk = integrator.stats["walk"]
                row["seconds"][jumps] = statistics.median(seconds)
                row["events"][jumps] = walk["events_per_path"]
                row["means"][jumps] = np.mean(means, axis=0)
                row["jumps"] = walk["jumps_per_path"]
            row["mean_ratio"] = (row["means"]["on"] / row["means"]["off"]).tolist()
            del row["means"]
            rows.append(row)
            print(f"{name:28s} shading {row['seconds']['off']:.3f} -> {row['seconds']['on']:.3f} s "
                  f"({row['seconds']['off'] / row['seconds']['on']:.2f}x), events/path {row['events']['off']:.2f} -> "
                  f"{row['events']['on']:.2f}, jumps/path {row['jumps']:.3f}, mean on/off "
                  f"{'/'.join(f'{r:.4f}' for r in row['mean_ratio'])}", flush=True)
    finally:
        objects.DIFFUSION_SPAN = span
    return rows


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenes", nargs="+")
    parser.add_argument("--width", type=int, default=64)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--force-walks", action="store_true")
    options = parser.parse_args()
    bench_jumps(options.scenes, options.width, options.spp, options.runs, options.force_walks)
