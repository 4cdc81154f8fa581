"""Resident memory over many renders of different presets in one process (issue 30: RSS flat within 50 MiB).

    PYTHONPATH=src python docs/history/scripts/reliability-memory.py [RENDERS [SIZE]]

Renders the bundled bunny (20 mm, null boundary, SIZE² pixels, default 64, 1 spp) with the first RENDERS presets
of ``convsss materials`` (default 30) in turn, in one process (a preset refused before any allocation counts as a
run), and prints the resident set size after each (``/proc/self/status`` VmRSS), then the growth from the first
render to the last and from the fifth on.
"""

import sys
import time

import convsss
from convsss.materials import catalog
from convsss.scene.quick import demo_mesh, quick_scene


def rss_mib():
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:")) / 1024


def main(renders=30, size=64):
    mi = convsss.register()
    presets = catalog()[:int(renders)]
    rows = []
    for k, material in enumerate(presets):
        start = time.perf_counter()
        scene = mi.load_dict(quick_scene(demo_mesh(), material, 20.0, int(size), int(size), 1, boundary="null"))
        try:
            convsss.render(scene)
            what = "rendered"
        except convsss.ConvsssError as error:  # refused before allocating: it counts as a run all the same
            what = f"refused: {str(error)[:40]}"
        del scene
        rows.append(rss_mib())
        print(f"{k + 1:3d} {material.name:24s} {rows[-1]:8.1f} MiB  {time.perf_counter() - start:5.1f} s  {what}",
              flush=True)
    print(f"growth: first -> last {rows[-1] - rows[0]:+.1f} MiB; render 5 -> last {rows[-1] - rows[4]:+.1f} MiB; "
          f"peak {max(rows):.1f} MiB over {len(rows)} renders")


if __name__ == "__main__":
    main(*sys.argv[1:])
