"""Inverse rendering with convsss, Mitsuba's way: recover a translucent bunny's material from a path-traced image.

The target is a ``volpathmis`` render (plain Mitsuba, many samples) of a 20 mm skin1 bunny; the scene to optimise is
the same bunny whose medium starts far off (albedo x 0.7, mean free path x 3). An Adam loop over ``mi.traverse``
renders it with the ``convsss`` integrator (``walk_depth`` inf: its random walk, whose derivatives with respect to a
homogeneous medium's ``albedo`` and ``sigma_t`` ``dr.backward`` gives), a few samples per pixel and a new seed per
step, and moves the medium's parameters (through latent variables: the albedo's logit and sigma_t's log, so that
they stay in range).

    python examples/inverse.py [WIDTH] [SPP] [STEPS] [TARGET_SPP]

prints the material per channel (albedo, mean free path in mm) at the start, recovered and true, and the relative
errors; ``CONVSSS_EXAMPLE_OUT`` (a folder) also gets the target, the start's and the result's images and the loss.
"""

import os
import sys
import time

import drjit as dr
import numpy as np

import convsss
from convsss.scene.quick import demo_mesh, quick_scene

mi = convsss.register()

ALBEDO = "bunny.interior_medium.albedo.value.value"
SIGMA_T = "bunny.interior_medium.sigma_t.value.value"


def bunny(material, width, spp, integrator):
    """The quick scene's 20 mm bunny of ``material`` (null boundary, its key and back lights), a box filter."""
    scene = quick_scene(demo_mesh(), material, 20.0, width=width, height=width, spp=spp, boundary="null",
                        integrator=integrator, rfilter="box")
    scene["bunny"] = scene.pop(next(k for k, v in scene.items() if isinstance(v, dict) and "interior" in v))
    return mi.load_dict(scene)


def recover(width=64, spp=8, steps=200, target_spp=1024, learning_rate=0.05, out=None):
    """The Adam loop; returns ``(start, recovered, truth)``, each ``(albedo, mfp_mm)`` per channel, and the losses."""
    truth_material = convsss.material("skin1")
    target = mi.render(bunny(truth_material, width, target_spp, {"type": "volpathmis", "max_depth": -1}),
                       seed=12345, spp=target_spp)[..., :3]
    scene = bunny(truth_material, width, spp, {"type": "convsss", "walk_depth": "inf"})
    params = mi.traverse(scene)
    truth = (np.array(params[ALBEDO], dtype=np.float64).ravel(), np.array(params[SIGMA_T], dtype=np.float64).ravel())
    scale = params["bunny.interior_medium.scale"]  # sigma_t = scale * value (per scene unit, here mm)

    # The start: albedo x 0.7, mean free path x 3 (sigma_t / 3).
    opt = mi.ad.Adam(lr=learning_rate)
    opt["logit_albedo"] = mi.Color3f(np.log(0.7 * truth[0] / (1 - 0.7 * truth[0])))
    opt["log_sigma_t"] = mi.Color3f(np.log(truth[1] / 3.0))

    def update():
        params[ALBEDO] = dr.rcp(1.0 + dr.exp(-opt["logit_albedo"]))
        params[SIGMA_T] = dr.exp(opt["log_sigma_t"])
        params.update()

    def material():
        albedo = np.array(params[ALBEDO], dtype=np.float64).ravel()
        return albedo, 1.0 / (scale * np.array(params[SIGMA_T], dtype=np.float64).ravel())

    update()
    start, losses = material(), []
    weight = 1.0 / dr.mean(target, axis=None)  # the error relative to the target's mean
    first = None
    for step in range(steps):
        # A new seed per step (and another for the gradient's paths, so that the image's noise and the gradient's
        # are independent); the step size falls tenfold over the run.
        image = mi.render(scene, params, seed=step, seed_grad=steps + step, spp=spp)[..., :3]
        first = image if first is None else first
        loss = dr.mean(dr.square((image - target) * weight), axis=None)
        dr.backward(loss)
        opt.set_learning_rate(learning_rate * 0.1 ** (step / steps))
        opt.step()
        update()
        losses.append(float(loss.array[0]))
    recovered = material()
    if out:
        from convsss.image import save_png

        os.makedirs(out, exist_ok=True)
        for name, picture in (("target", target), ("start", first), ("recovered", image)):
            save_png(os.path.join(out, f"inverse-{name}.png"), np.array(picture))
        np.savetxt(os.path.join(out, "inverse-loss.txt"), losses)
    return start, recovered, (truth[0], 1.0 / (scale * truth[1])), losses


def main(argv):
    width, spp, steps, target_spp = (int(a) for a in (argv + ["64", "8", "200", "1024"][len(argv):]))
    begun = time.perf_counter()
    start, recovered, truth, losses = recover(width, spp, steps, target_spp, out=os.environ.get("CONVSSS_EXAMPLE_OUT"))
    seconds = time.perf_counter() - begun
    print(f"a 20 mm skin1 bunny, {width}x{width}: target volpathmis {target_spp} spp; Adam, {steps} steps of {spp} spp "
          f"({seconds:.1f} s in all; the loss, mostly the {spp}-spp images' noise: {np.median(losses[:10]):.3g} over the "
          f"first 10 steps, {np.median(losses[-10:]):.3g} over the last 10)")
    print("| | albedo R / G / B | mean free path (mm) R / G / B |")
    print("|---|---|---|")
    for name, (albedo, mfp) in (("start", start), ("recovered", recovered), ("truth", truth)):
        print(f"| {name} | {' / '.join(f'{a:.4f}' for a in albedo)} | {' / '.join(f'{m:.4f}' for m in mfp)} |")
    albedo_error = np.abs(recovered[0] / truth[0] - 1)
    mfp_error = np.abs(recovered[1] / truth[1] - 1)
    print(f"| error | {' / '.join(f'{e:.1%}' for e in albedo_error)} | {' / '.join(f'{e:.1%}' for e in mfp_error)} |")


if __name__ == "__main__":
    main(sys.argv[1:])
