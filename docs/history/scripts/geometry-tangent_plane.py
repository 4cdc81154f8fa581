"""Light that crosses an object: an experiment, not a transport (docs/benchmarks.md, "Light through the object:
kernels that see the receiver's plane").

    PYTHONPATH=src python docs/history/scripts/geometry-tangent_plane.py SCENE.xml RENDER.exr REFERENCE.exr [FIGURE.png]
    PYTHONPATH=src python docs/history/scripts/geometry-tangent_plane.py --limits     # the plane and thick-slab limits, checked

SCENE.xml is a `convsss scene` file (one translucent object), RENDER.exr a `convsss render SCENE.xml --aovs mask` of
it and REFERENCE.exr its `convsss reference`. At the pixel centres that see the object, the script sums Eq. 1 exactly
over the render's own irradiance samples (their positions, normals and flux) with the half-space dipole, and with
six kernels that also see the receiver's tangent plane; the render times each ratio of two sums estimates the
render with that kernel. It prints each one's mean over the object / the reference's and the mean per-pixel error.

The classic dipole (Jensen et al. 2001) puts a source of the sample's flux at depth ``z_r`` under the entry point
``x_i`` and a negative image ``z_v = z_r + 2 z_b`` above it, both about the entry point's plane, and reads the flux
through that same plane at the receiver ``x_o`` (Eq. T1):

    R_d(r) = alpha'/(4 pi) [z_r f(d_r) + z_v f(d_v)],   f(d) = (1 + sigma_tr d) e^{-sigma_tr d} / d^3.

Where the receiver faces away from the entry point (light through the object) the flux leaves through the receiver's
own plane. For a source ``s`` at depth ``t = n_o . (x_o - s)`` under the receiver's tangent plane, its image about
that plane's extrapolated boundary gives the flux (Eq. T2)

    K(s) = alpha'/(4 pi) [t f(|x_o - s|) + (t + 2 z_b) f(sqrt(|x_o - s|^2 + 4 z_b t + 4 z_b^2))],

and the tangent-plane kernel takes the entry point's source and its image through it (Eq. T3):

    K_tp = max(0, K(x_i - z_r n_i) - w K(x_i + z_v n_i)),   w = clamp((t_v + z_v) / (2 z_v), 0, 1),

``t_v`` the image's depth under the receiver's plane. On a plane (``n_o = n_i``, ``t_v = -z_v``, ``w = 0``) it is
Eq. T1 exactly; across a slab (``n_o = -n_i``, ``w = 1``) its four sources are the first terms of the slab's series
of images, whose total is ``2 alpha' sinh(sigma_tr (z_r + z_b)) cosh(sigma_tr z_b) e^{-sigma_tr (d + 2 z_b)}``,
the thick-slab limit of `docs/history/scripts/incidence-transmission.py`'s exact transmission. The blend (Eq. T4) keeps Eq. T1
where the two normals agree and Eq. T3 where they are opposite:

    K_blend = (1 - beta) R_d + beta K_tp,   beta = max(0, -n_o . n_i).

Two more planes through the receiver for Eq. T3, which keep the plane case exact: the mid plane, normal
``n_o + n_i`` (it holds both points of a sphere), where the normals agree, and the exit plane where they are
opposite (Eq. T5); and a plane leaning from the mid plane to the exit plane as the normals turn apart, normal
``n_o + max(0, n_o . n_i) n_i``, continuous in the normals (Eq. T6). Last, two blends of Eq. T1 and T3 by the
angle of the chord to the receiver's plane, which is small between near points of a convex surface and near 90°
across the object (Eq. T7, T8):

    K = (1 - gamma) R_d + gamma K_tp,   gamma = clamp(n_o . (x_o - x_i) / |x_o - x_i|, 0, 1)   (T7),  gamma^2  (T8).

Optical parameters: the object's material at the boundary's eta (1 for a null boundary), the dipole's own (its
total, not the exact one: the ratio of two sums does not see a per-channel scale). The sums are O(points x samples):
minutes at 128².
"""

import dataclasses
import math
import sys
import time

import numba
import numpy as np

import convsss
from convsss.compare import mask_layer, metrics
from convsss.image import luminance, read_image, read_layers
from convsss.profiles.models import model_profile


@numba.njit(inline="always")
def _f(d, sigma):
    return (1.0 + sigma * d) * math.exp(-sigma * d) / (d * d * d)


@numba.njit(inline="always")
def _tangent_plane_flux(t, d2, z_b, sigma, floor):
    """Eq. T2 without alpha'/(4 pi): a source at depth ``t`` under the plane, ``d2`` = its squared distance to the
    receiver."""
    d1 = math.sqrt(max(d2, floor))
    d_image = math.sqrt(max(d2 + 4.0 * z_b * t + 4.0 * z_b * z_b, floor))
    return t * _f(d1, sigma) + (t + 2.0 * z_b) * _f(d_image, sigma)


@numba.njit(inline="always")
def _plane_kernel(plane, d, r2, n_i, z_r, z_b, sigma):
    """Eq. T3 for the plane through the receiver with normal ``plane`` (3-tuple, any length > 0); ``d = x_o - x_i``
    and ``n_i`` 3-tuples, ``r2 = |d|^2``."""
    norm = math.sqrt(plane[0] * plane[0] + plane[1] * plane[1] + plane[2] * plane[2])
    p_d = (plane[0] * d[0] + plane[1] * d[1] + plane[2] * d[2]) / norm
    p_ni = (plane[0] * n_i[0] + plane[1] * n_i[1] + plane[2] * n_i[2]) / norm
    ni_d = n_i[0] * d[0] + n_i[1] * d[1] + n_i[2] * d[2]
    z_v = z_r + 2.0 * z_b
    t_r, t_v = p_d + z_r * p_ni, p_d - z_v * p_ni
    value = _tangent_plane_flux(t_r, r2 + 2.0 * z_r * ni_d + z_r * z_r, z_b, sigma, z_r * z_r)
    w = min(max((t_v + z_v) / (2.0 * z_v), 0.0), 1.0)
    if w > 0.0:
        value -= w * _tangent_plane_flux(t_v, r2 - 2.0 * z_v * ni_d + z_v * z_v, z_b, sigma, z_r * z_r)
    return max(value, 0.0)


@numba.njit(parallel=True, fastmath=True)
def kernel_sums(points, normals, positions, sample_normals, flux, z_r, z_b, sigma):
    """Per point (K, 3): Eq. 1 with Eq. T1, T3 to T8 (rows 0 to 6), without the common alpha'/(4 pi)."""
    out = np.zeros((7, points.shape[0], 3))
    for k in numba.prange(points.shape[0]):
        n_o = (normals[k, 0], normals[k, 1], normals[k, 2])
        for i in range(positions.shape[0]):
            n_i = (sample_normals[i, 0], sample_normals[i, 1], sample_normals[i, 2])
            d = (points[k, 0] - positions[i, 0], points[k, 1] - positions[i, 1], points[k, 2] - positions[i, 2])
            r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
            cos = n_o[0] * n_i[0] + n_o[1] * n_i[1] + n_o[2] * n_i[2]
            beta = max(0.0, -cos)
            middle = (n_o[0] + n_i[0], n_o[1] + n_i[1], n_o[2] + n_i[2])
            lean = max(cos, 0.0)
            leaning = (n_o[0] + lean * n_i[0], n_o[1] + lean * n_i[1], n_o[2] + lean * n_i[2])
            chord = n_o[0] * d[0] + n_o[1] * d[1] + n_o[2] * d[2]
            gamma = min(max(chord / max(math.sqrt(r2), 1e-12), 0.0), 1.0)
            for c in range(3):
                zr, zb, s = z_r[c], z_b[c], sigma[c]
                zv = zr + 2.0 * zb
                classic = zr * _f(math.sqrt(r2 + zr * zr), s) + zv * _f(math.sqrt(r2 + zv * zv), s)  # Eq. T1
                exit_plane = _plane_kernel(n_o, d, r2, n_i, zr, zb, s)  # Eq. T3
                out[0, k, c] += classic * flux[i, c]
                out[1, k, c] += exit_plane * flux[i, c]
                out[2, k, c] += ((1.0 - beta) * classic + beta * exit_plane) * flux[i, c]  # Eq. T4
                mid = _plane_kernel(middle, d, r2, n_i, zr, zb, s) if cos >= 0.0 else exit_plane
                out[3, k, c] += mid * flux[i, c]  # Eq. T5
                out[4, k, c] += _plane_kernel(leaning, d, r2, n_i, zr, zb, s) * flux[i, c]  # Eq. T6
                out[5, k, c] += ((1.0 - gamma) * classic + gamma * exit_plane) * flux[i, c]  # Eq. T7
                out[6, k, c] += ((1.0 - gamma * gamma) * classic + gamma * gamma * exit_plane) * flux[i, c]  # Eq. T8
    return out


def limits():
    """Every kernel is Eq. T1 on a plane; Eq. T3 transmits the thick slab's series of images (module docstring)."""
    z_r, z_b, sigma = np.array([1.0, 0.7, 0.5]), np.array([0.6, 0.5, 0.3]), np.array([0.3, 0.7, 1.4])
    rng = np.random.default_rng(0)
    up = np.array([0.0, 0.0, 1.0])
    positions = np.c_[rng.uniform(-5, 5, (2000, 2)), np.zeros(2000)]
    points = np.c_[rng.uniform(-3, 3, (5, 2)), np.zeros(5)]
    sums = kernel_sums(points, np.tile(up, (5, 1)), positions, np.tile(up, (2000, 1)), rng.uniform(0, 1, (2000, 3)),
                       z_r, z_b, sigma)
    print("plane, largest |T/T1 - 1| of T3..T8:", " ".join(f"{np.abs(s / sums[0] - 1).max():.1e}" for s in sums[1:]))
    thickness, h = 8.0, 0.05
    x, y = np.meshgrid(np.arange(-40, 40, h), np.arange(-40, 40, h))
    positions = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    sums = kernel_sums(np.array([[0.0, 0.0, -thickness]]), np.array([-up]), positions, np.tile(up, (x.size, 1)),
                       np.full((x.size, 3), h * h), z_r, z_b, sigma)[:, 0] / (4 * np.pi)
    series = 2 * np.sinh(sigma * (z_r + z_b)) * np.cosh(sigma * z_b) * np.exp(-sigma * (thickness + 2 * z_b))
    print(f"slab {thickness} mm thick, lit face to far face, total / series: T3", np.round(sums[1] / series, 4),
          " T1", np.round(sums[0] / series, 3))


def main(scene_file, render_file, reference_file, figure=None):
    mi = convsss.register()
    scene = mi.load_file(scene_file)
    integrator = mi.load_dict({"type": "convsss"})
    integrator.prepare(scene, scene.sensors()[0], 0)
    state, unit = integrator.prepared, integrator.params.unit_mm
    obj, samples = state.objects[0], state.transports[0].samples
    eta = 1.0 if obj.boundary == "null" else obj.material.eta
    dipole = model_profile("dipole", dataclasses.replace(obj.material, eta=eta), total="model")
    z_r, sigma = np.asarray(dipole.z_r, float), np.asarray(dipole.sigma_tr, float)
    z_b = 0.5 * (np.asarray(dipole.z_v, float) - z_r)

    sensor = scene.sensors()[0]
    width, height = sensor.film().size()
    x, y = np.meshgrid(np.arange(width), np.arange(height))
    uv = mi.Point2f(((x.ravel() + 0.5) / width).astype(np.float32), ((y.ravel() + 0.5) / height).astype(np.float32))
    ray, _ = sensor.sample_ray(0.0, 0.5, uv, mi.Point2f(0.5, 0.5))
    si = scene.ray_intersect(ray)
    seen = np.array(si.is_valid())
    points = np.array(si.p).T[seen] * unit
    normals = np.array(si.sh_frame.n).T[seen]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)

    start = time.perf_counter()
    sums = kernel_sums(points, normals, samples.position, samples.normal, samples.flux, z_r, z_b, sigma)
    print(f"{len(samples)} samples, {len(points)} points: {time.perf_counter() - start:.0f} s")

    render, reference = read_image(render_file), read_image(reference_file)
    mask = mask_layer(read_layers(render_file))[1]
    ratios = {}
    for name, row in (("exit plane (T3)", 1), ("blend (T4)", 2), ("mid plane (T5)", 3), ("leaning (T6)", 4),
                      ("chord (T7)", 5), ("chord squared (T8)", 6)):
        ratio = np.ones((height * width, 3))
        ratio[seen] = sums[row] / np.maximum(sums[0], 1e-300)
        ratios[name] = ratio.reshape(height, width, 3)

    def summary(image):
        m = metrics(reference, image, mask)  # convsss compare's mean ratio and mean per-pixel error
        return " ".join(f"{v:.3f}" for v in m["mean_ratio"]), " ".join(f"{100 * v:.1f}" for v in m["mean_rel_error"])

    print(f"{'kernel':22s} mean / reference (R G B)   mean per-pixel error, % (R G B)")
    for name, image in [("half-space dipole (T1)", render)] + [(n, render * r) for n, r in ratios.items()]:
        mean, error = summary(image)
        print(f"{name:22s} {mean:27s} {error}")
    if figure:
        _figure(render, reference, ratios, mask, figure)


def _figure(render, reference, ratios, mask, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    images = [("Eq. T1 (half-space)", render)] + [(n, render * r) for n, r in ratios.items()]
    rows, cols = np.nonzero(mask)
    crop = np.s_[max(rows.min() - 2, 0):rows.max() + 3, max(cols.min() - 2, 0):cols.max() + 3]
    fig, axes = plt.subplots(1, len(images), figsize=(3.2 * len(images) + 1, 3.4), squeeze=False)
    for ax, (name, image) in zip(axes[0], images):
        ratio = np.where(mask, luminance(image) / np.maximum(luminance(reference), 1e-9), np.nan)
        shown = ax.imshow(ratio[crop], vmin=0.5, vmax=1.5, cmap="coolwarm")
        ax.set_title(name, fontsize=10)
        ax.axis("off")
    fig.colorbar(shown, ax=axes[0].tolist(), shrink=0.8, label="luminance / path tracing")
    fig.savefig(path, dpi=80)


if __name__ == "__main__":
    if sys.argv[1:] == ["--limits"]:
        limits()
    else:
        main(*sys.argv[1:5])
