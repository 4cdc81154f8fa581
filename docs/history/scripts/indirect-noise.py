"""Noise that indirect light leaves in the demo image (docs/benchmarks.md): the demo scene (40 mm bunny, floor, 8
layers, Phong, 16 spp, seed 0) compared (convsss.compare, over the bunny's pixels) against the same render with 16
indirect paths per sample, cached in out/indirect-cache/: only the indirect irradiance differs.

    PYTHONPATH=src python docs/history/scripts/indirect-noise.py WIDTH MATERIAL PATHS:STRATA[,PATHS:STRATA...]
"""

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from ratio import convsss, demo_mesh, mask_of, mi, np, quick_scene  # noqa: E402

import convsss.pipeline.irradiance as IR  # noqa: E402
from convsss.compare import compare  # noqa: E402

W = int(sys.argv[1])
material = sys.argv[2]
variants = [v.split(":") for v in sys.argv[3].split(",")]  # paths:strata
d = quick_scene(demo_mesh(), convsss.material(material), 40, W, W, 16, floor=True)


def render(paths, strata):
    IR.DIRECTION_STRATA = strata
    scene = mi.load_dict(
        {**d, "integrator": {"type": "convsss", "specular": "phong", "layers": 8, "indirect_samples": paths}}
    )
    img = np.array(scene.integrator().render(scene, scene.sensors()[0], seed=0), dtype=np.float64)[..., :3]
    return img, scene, scene.integrator().stats


Path("out/indirect-cache").mkdir(parents=True, exist_ok=True)
ref_path = f"out/indirect-cache/noise-ref-{material}-{W}.npy"
if os.path.exists(ref_path):
    ref = np.load(ref_path)
else:
    ref, _, _ = render(16, 4)
    np.save(ref_path, ref)
mask = mask_of(mi.load_dict(d))
for paths, strata in variants:
    img, scene, st = render(float(paths), int(strata))
    m = compare(ref, img, mask[..., None].repeat(3, 2))
    s = st["seconds"]
    print(
        f"{material} {W}px paths={paths} strata={strata}: "
        f"mean_rel_error {np.round(100 * np.array(m['mean_rel_error']), 2)} %  "
        f"rel_rms {np.round(100 * np.sqrt(np.array(m['relmse'])), 2)} %  mean_ratio {np.round(m['mean_ratio'], 4)}  "
        f"indirect {s.get('indirect', 0):.2f}s transport {s['transport']:.2f}s",
        flush=True,
    )
