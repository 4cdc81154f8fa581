"""The layered convolution transport of Munoz et al. 2011 (§4–5).

1. **Layers** (§4.2): ``n_l`` planes perpendicular to the view axis at depths ``z_l = min z + l dz``,
   ``dz = (max z - min z)/(n_l - 1)``, over the samples' depth range.
2. **Splatting**: each sample's flux ``Phi_i = E_i A_i`` goes to the grid bilinearly in x, y and to its two nearest
   layers, linearly in depth (``splat="linear"``) or half and half (``splat="half"``, the paper's rule).
3. **Kernels** (Eq. 5): ``K_m = R_d(sqrt(r^2 + (m dz)^2))`` as cell averages (:mod:`.kernels`).
4. **Exitance** (Eq. 6): ``M_l = sum_i K_{|i-l|} * Phi_i`` — by linearity one forward FFT per non-empty source
   layer, one fused per-frequency mixing pass ``M^_l = sum_i K^_{|i-l|} Phi^_i``, and one inverse FFT per output
   layer that a query needs (the paper's visible-layer optimization). Convolutions are linear: the FFT grid is
   padded by the kernel's reach (bounded by the grid), so nothing wraps around.
5. **Threshold** (Eq. 8, per channel): the pair (i, l) is skipped when ``R_d(|i-l| dz) < t R_d(0)``.
6. **Lookup** (Eq. 7): bilinear in x, y inside the two layers that bracket the point, linear in depth.
7. **Plane correction** (beyond the paper, ``correction="plane"``, needs the query normals): adds what the depth
   discretization misses for a locally uniform irradiance, or removes its excess share of what the layers deposited;
   exact for any uniformly lit plane; it never turns a non-negative exitance negative (:mod:`.correction`).

Cells are ``cell_size / downsample`` mm wide (``downsample`` 1, 1/2, 1/4: the paper's lower-resolution layers).
"""

from dataclasses import dataclass

import numpy as np

from ..errors import ConvsssError
from ..jit import njit, prange
from ..memory import check_memory
from ..parameters import Parameter, check_parameters
from ..samples import ViewFrame
from .base import Transport, register_transport
from .correction import apply_correction, cached_plane_response
from .kernels import kernel_spectra, profile_key

SPLATS = ("linear", "half")
CORRECTIONS = ("none", "plane")
DOWNSAMPLES = (1.0, 0.5, 0.25)
#: Mixing costs layers^2 per frequency; the paper uses 2-16 layers, and 256 is already far past any gain.
MAX_LAYERS = 256
DEFAULT_RESOLUTION = 512


@njit(cache=True)
def _layer_of(z, z0, dz, n_layers):
    """Lower bracketing layer and the depth weight of the upper one (0 with a single layer)."""
    if n_layers == 1:
        return 0, 0.0
    u = (z - z0) / dz
    lo = min(max(int(np.floor(u)), 0), n_layers - 2)
    return lo, min(max(u - lo, 0.0), 1.0)


@njit(cache=True)
def _bucket_by_layer(view, z0, dz, n_layers):
    """Counting sort of the samples by their lower bracketing layer: ``order`` and bucket ``starts`` (n_l + 1)."""
    lower = np.empty(view.shape[0], dtype=np.int64)
    starts = np.zeros(n_layers + 1, dtype=np.int64)
    for k in range(view.shape[0]):
        lower[k], _ = _layer_of(view[k, 2], z0, dz, n_layers)
        starts[lower[k] + 1] += 1
    for layer in range(n_layers):
        starts[layer + 1] += starts[layer]
    order = np.empty(view.shape[0], dtype=np.int64)
    fill = starts[:-1].copy()
    for k in range(view.shape[0]):
        order[fill[lower[k]]] = k
        fill[lower[k]] += 1
    return order, starts


@njit(parallel=True, cache=True)
def _splat(view, flux, x0, y0, h, z0, dz, n_layers, half, grid):
    """Add each sample's flux (N, C) to 4 cells x 2 layers of ``grid`` (n_l, C, Py, Px); return each layer's total.

    One thread per output layer, each reading the samples bucketed below and above it in a fixed order, so the
    result is the same bit for bit whatever the thread count.
    """
    channels, height, width = grid.shape[1], grid.shape[2], grid.shape[3]
    order, starts = _bucket_by_layer(view, z0, dz, n_layers)
    deposited = np.zeros(n_layers)
    for layer in prange(n_layers):
        for upper in range(2 if n_layers > 1 else 1):
            lower = layer - upper  # samples whose lower layer is `lower` reach `layer` as their upper one
            if lower < 0 or lower >= max(n_layers - 1, 1):
                continue
            for idx in range(starts[lower], starts[lower + 1]):
                k = order[idx]
                gx = (view[k, 0] - x0) / h
                gy = (view[k, 1] - y0) / h
                i = min(max(int(np.floor(gx)), 0), width - 2)
                j = min(max(int(np.floor(gy)), 0), height - 2)
                fx = gx - i
                fy = gy - j
                _, w_hi = _layer_of(view[k, 2], z0, dz, n_layers)
                if half and n_layers > 1:
                    w_hi = 0.5
                wl = w_hi if upper == 1 else 1.0 - w_hi  # paper §4.1: irradiance into the two nearest layers
                deposited[layer] += wl * np.sum(flux[k])
                for dj in range(2):
                    wy = fy if dj == 1 else 1.0 - fy
                    for di in range(2):
                        w = wl * wy * (fx if di == 1 else 1.0 - fx)
                        for c in range(channels):
                            grid[layer, c, j + dj, i + di] += w * flux[k, c]
    return deposited


@njit(parallel=True, fastmath=True, cache=True)
def _mix(phi_hat, kernel_hat, out_layers, source_layers, keep, out):
    """``out[o] = sum_s K^[|source_layers[s] - out_layers[o]|] * phi_hat[s]`` over the pairs kept per channel."""
    n_freq_y, n_freq_x = out.shape[2], out.shape[3]
    for ky in prange(n_freq_y):
        for o in range(out_layers.shape[0]):
            for c in range(3):
                row = out[o, c, ky]
                for s in range(source_layers.shape[0]):
                    m = abs(source_layers[s] - out_layers[o])
                    if not keep[m, c]:
                        continue
                    k_row = kernel_hat[m, c, ky]  # paper Eq. 6: M^_l += K^_{|i-l|} E^_i, per frequency
                    p_row = phi_hat[s, c, ky]
                    for kx in range(n_freq_x):
                        row[kx] += k_row[kx] * p_row[kx]


@njit(parallel=True, fastmath=True, cache=True)
def _lookup(view, x0, y0, h, z0, dz, n_layers, exitance, out):
    """Bilinear in x, y within the two bracketing layers of ``exitance`` (n_l, C, H, W), linear in depth (Eq. 7)."""
    channels, height, width = exitance.shape[1], exitance.shape[2], exitance.shape[3]
    for k in prange(view.shape[0]):
        gx = min(max((view[k, 0] - x0) / h, 0.0), width - 1.0)
        gy = min(max((view[k, 1] - y0) / h, 0.0), height - 1.0)
        i = min(int(gx), width - 2)
        j = min(int(gy), height - 2)
        fx = gx - i
        fy = gy - j
        lo, w_hi = _layer_of(view[k, 2], z0, dz, n_layers)
        for c in range(channels):
            acc = 0.0
            for dl in range(2 if n_layers > 1 else 1):
                wl = w_hi if dl == 1 else 1.0 - w_hi
                layer = exitance[lo + dl, c]
                bilinear = ((1 - fy) * ((1 - fx) * layer[j, i] + fx * layer[j, i + 1])
                            + fy * ((1 - fx) * layer[j + 1, i] + fx * layer[j + 1, i + 1]))
                acc += wl * bilinear  # paper Eq. 7: M linear between the two nearest layers
            out[k, c] = acc


@njit(cache=True)
def _needed_layers(view, z0, dz, n_layers):
    """Which layers bracket at least one of the points."""
    need = np.zeros(n_layers, dtype=np.bool_)
    for k in range(view.shape[0]):
        lo, _ = _layer_of(view[k, 2], z0, dz, n_layers)
        need[lo] = True
        if n_layers > 1:
            need[lo + 1] = True
    return need


@dataclass(frozen=True)
class LayerGrid:
    """The layers' geometry: image-plane ``cell`` (mm), ``n_layers`` from depth ``z0`` every ``dz``, the grid's
    corner ``x0``, ``y0``, its ``grid_shape`` (H, W), the kernel's ``reach`` in cells and the FFT's
    ``padded_shape``."""

    cell: float
    n_layers: int
    z0: float
    dz: float
    x0: float
    y0: float
    grid_shape: tuple
    reach: tuple
    padded_shape: tuple


def layer_grid(lo, hi, layers, cell_size, resolution, downsample, profile, kernel_tail):
    """The :class:`LayerGrid` over samples within ``lo``, ``hi`` (3,) of the view frame: cells of ``cell_size /
    downsample`` (default: the image-plane extent / ``resolution``), ``layers`` layers over the depth range (one for
    a flat object), kernels reaching the radius that holds all but ``kernel_tail`` of the profile's energy."""
    import scipy.fft

    extent = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    if cell_size is None:
        cell_size = max(extent, 1e-9) / (resolution or DEFAULT_RESOLUTION)
    cell = float(cell_size) / downsample
    depth_range = float(hi[2] - lo[2])
    flat = depth_range <= 1e-9 * max(extent, depth_range, 1e-300)
    n_layers = 1 if (layers == 1 or flat) else int(layers)
    width = int(np.ceil((hi[0] - lo[0]) / cell)) + 3
    height = int(np.ceil((hi[1] - lo[1]) / cell)) + 3
    reach = int(np.ceil(float(np.max(profile.radius_energy(kernel_tail))) / cell))
    reach = (min(reach, height - 1), min(reach, width - 1))
    padded = tuple(scipy.fft.next_fast_len(n + q, real=True) for n, q in zip((height, width), reach))
    return LayerGrid(cell, n_layers, float(lo[2]), depth_range / (n_layers - 1) if n_layers > 1 else 0.0,
                     float(lo[0]) - cell, float(lo[1]) - cell, (height, width), reach, padded)


def grid_bytes(n_layers, grid_shape, padded_shape, correction):
    """Bytes held at the peak: the splat grid, source spectra, kernel spectra, one batch of output spectra and its
    inverse, the exitance layers, and the plane correction's irradiance grids (2 sides x 4 channels)."""
    py, px = padded_shape
    spatial = n_layers * 3 * py * px * 4
    spectrum = n_layers * 3 * py * (px // 2 + 1)
    layers = n_layers * 3 * grid_shape[0] * grid_shape[1] * 4
    return int(spatial + spectrum * 8 + spectrum * 4 + spectrum * 8 + spatial + layers
               + (8 * layers // 3 if correction == "plane" else 0))


class ConvolutionTransport(Transport):
    """Layered FFT convolution transport; see the module docstring.

    Parameters
    ----------
    samples : IrradianceSamples
    profile : Profile
    frame : ViewFrame
        The camera frame; layers are perpendicular to ``frame.forward``.
    **params
        The declared :attr:`parameters` (``convsss.transport.TRANSPORTS["convolution"].parameters``): ``layers``,
        ``threshold``, ``downsample``, ``splat``, ``correction``; and, set by the renderer or a numpy caller,
        ``cell_size`` (or ``resolution``), ``memory_limit``, ``kernel_tail``, ``workers``.
    """

    name = "convolution"
    parameters = (
        Parameter("layers", int, 8, "Layers parallel to the image plane (paper §4; 4-8 is the paper's trade-off).",
                  low=2, high=MAX_LAYERS),
        Parameter("threshold", float, 1e-3, "Skip layer pairs whose profile falls below this fraction of R_d(0) "
                  "(paper Eq. 8; 0 keeps every pair).", low=0.0, high=0.999),
        Parameter("downsample", float, 1.0, "Layer resolution relative to the image (paper §5, Fig. 3).",
                  choices=DOWNSAMPLES),
        Parameter("splat", str, "linear", "Irradiance into the two nearest layers: by depth (linear) or half and half "
                  "(the paper's rule).", choices=SPLATS),
        Parameter("correction", str, "plane", "plane: correct the layers' depth discretization with their exact "
                  "response to the surface's tangent plane (beyond the paper); none: the paper's method as "
                  "published.", choices=CORRECTIONS),
        Parameter("cell_size", float, None, "Grid cell in mm at full resolution (the pixel footprint at the "
                  "object); default: the samples' image-plane extent / resolution.", low=0.0, low_open=True,
                  exposed=False),
        Parameter("resolution", int, None, "Cells across the larger image-plane extent when cell_size is not given "
                  f"(default {DEFAULT_RESOLUTION}).", low=2, exposed=False),
        Parameter("memory_limit", float, None, "Refuse grids needing more bytes (default: 75 % of available "
                  "memory).", low=0.0, low_open=True, exposed=False),
        Parameter("kernel_tail", float, 1e-4, "Kernels reach the radius holding all but this fraction of the "
                  "profile's energy (bounded by the grid).", low=0.0, high=0.1, low_open=True, exposed=False),
        Parameter("workers", int, -1, "Threads for scipy.fft (-1: all cores).", low=-1, exposed=False),
    )

    def __init__(self, samples, profile, frame, material=None, **params):
        import scipy.fft

        super().__init__(samples, profile, frame, material, **params)
        p = self.params
        if not isinstance(frame, ViewFrame):
            raise ConvsssError("the convolution transport needs the camera's ViewFrame (frame=...)")
        if p["cell_size"] is not None and p["resolution"] is not None:
            raise ConvsssError("give the grid's cell_size or its resolution, not both")
        self.workers = p["workers"]
        self.threshold, self.splat, self.downsample = p["threshold"], p["splat"], p["downsample"]
        self.correction = p["correction"]

        with self.timings("splat"):
            self._view = frame.to_view(samples.position)
            self._setup_grid(p["layers"], p["cell_size"], p["resolution"], profile, p["kernel_tail"])
        # The plane correction applies where there is depth to discretize: more than one layer.
        self._corrects = self.correction == "plane" and self.n_layers > 1
        if self._corrects and samples.normal is None:
            raise ConvsssError("the plane correction needs the samples' normals (or correction='none')")
        self.memory_bytes = self._memory_estimate()
        check_memory(self.memory_bytes, f"the convolution grid {self.grid_shape} x {self.n_layers} layers (FFT "
                     f"{self.padded_shape})", "use fewer layers, a lower resolution or downsample", p["memory_limit"])
        with self.timings("splat"):
            grid = np.zeros((self.n_layers, 3) + self.padded_shape, dtype=np.float32)
            deposited = _splat(self._view, np.ascontiguousarray(samples.flux), self.x0, self.y0, self.cell, self.z0,
                               self.dz, self.n_layers, self.splat == "half", grid)
            self.source_layers = np.flatnonzero(deposited > 0).astype(np.int64)
        with self.timings("kernels"):
            table = profile.radial_table()
            r_core = float(np.min(profile.radius_below(0.5)))
            self._kernel_hat, self.kernel_energy, self.kernels_cached = kernel_spectra(
                table, r_core, self.cell, self.dz, self.n_layers, self.reach, self.padded_shape, self.workers)
            at_layers = profile(self.dz * np.arange(self.n_layers))
            self.keep = at_layers >= self.threshold * profile(0.0)[None, :]  # paper Eq. 8, per channel
        if self._corrects:
            with self.timings("correction"):
                self._response = cached_plane_response(profile, profile_key(table), self.dz, self.splat)
                self._irradiance_grids = self._splat_irradiance()
        with self.timings("forward_fft"):
            sources = grid if len(self.source_layers) == self.n_layers else grid[self.source_layers]
            self._phi_hat = scipy.fft.rfft2(sources, workers=self.workers, overwrite_x=True)
        del grid
        self._exitance_layers = np.zeros((self.n_layers, 3) + self.grid_shape, dtype=np.float32)
        self.computed = np.zeros(self.n_layers, dtype=bool)

    def _setup_grid(self, layers, cell_size, resolution, profile, kernel_tail):
        lo, hi = self._view.min(axis=0), self._view.max(axis=0)
        grid = layer_grid(lo, hi, layers, cell_size, resolution, self.downsample, profile, kernel_tail)
        for name, value in vars(grid).items():
            setattr(self, name, value)

    def _memory_estimate(self):
        return grid_bytes(self.n_layers, self.grid_shape, self.padded_shape, self.correction)

    memory_advice = "use fewer layers, a lower resolution or downsample"

    @classmethod
    def layer_cell(cls, footprint, params):
        """The pixel footprint divided by ``downsample`` (paper §5: layers at a fraction of the image's
        resolution)."""
        return footprint / params.get("downsample", 1.0)

    @classmethod
    def planned_bytes(cls, bounds, profile, count, params, material=None):
        """The layers' grids and spectra (:func:`layer_grid`, :func:`grid_bytes`) over ``bounds``."""
        p = check_parameters(cls.parameters, params, f"the {cls.name} transport")
        grid = layer_grid(bounds[0], bounds[1], p["layers"], p["cell_size"], p["resolution"], p["downsample"],
                          profile, p["kernel_tail"])
        return grid_bytes(grid.n_layers, grid.grid_shape, grid.padded_shape, p["correction"])

    def compute_layers(self, layers):
        """Exitance images of ``layers`` (those not computed yet): mixing per frequency, then inverse FFTs.

        Parameters
        ----------
        layers : array_like of int
            Layer indices in ``0 .. n_layers - 1``, in any order, repeats allowed.

        Returns
        -------
        None
            The images are kept (float32, shape (3, H, W) each, in the irradiance's unit) for lookups and
            :meth:`layer_image`.
        """
        import scipy.fft

        todo = np.array([n for n in np.unique(layers) if not self.computed[n]], dtype=np.int64)
        if len(todo) == 0:
            return
        py, px = self.padded_shape
        with self.timings("mixing"):
            out = np.zeros((len(todo), 3, py, px // 2 + 1), dtype=np.complex64)
            _mix(self._phi_hat, self._kernel_hat, todo, self.source_layers, self.keep, out)
        with self.timings("inverse_fft"):
            spatial = scipy.fft.irfft2(out, s=self.padded_shape, workers=self.workers)
            height, width = self.grid_shape
            # Non-negative flux convolved with a non-negative kernel is non-negative; the FFT's float32 round-off
            # (about 1e-7 of the peak) is not, so values below zero are round-off and their true value is ~0.
            self._exitance_layers[todo] = np.maximum(spatial[:, :, :height, :width], 0.0)
        self.computed[todo] = True

    def _prepare(self, points):
        """The paper's visible-layer optimization: compute only the layers that bracket the query points."""
        view = self.frame.to_view(points)
        self.compute_layers(np.flatnonzero(_needed_layers(view, self.z0, self.dz, self.n_layers)))

    def _exitance(self, points):
        view = self.frame.to_view(points)
        out = np.empty((len(points), 3))
        _lookup(view, self.x0, self.y0, self.cell, self.z0, self.dz, self.n_layers, self._exitance_layers, out)
        return out

    def _correct(self, points, normals, exitance):
        """The plane correction (:mod:`.correction`, Eq. P1 and P2) of the layers' exitance, in place."""
        if not self._corrects:
            return
        with self.timings("correction"):
            view = self.frame.to_view(points)
            depth = (view[:, 2] - self.z0) / self.dz
            w = depth - np.clip(np.floor(depth), 0, self.n_layers - 2)
            cos_theta = np.abs(normals @ self.frame.forward)
            apply_correction(exitance, cos_theta, w, self._nearby_irradiance(view, normals), self._response,
                             self.profile.total_reflectance)

    def _splat_irradiance(self):
        """Per side (facing the camera or away), ``sum w E_i A_i`` (3 channels) and ``sum w A_i`` on the layer grid,
        splatted with the exitance lookup's weights: their ratio at a point is the local irradiance ``E_q``."""
        facing = self.samples.normal @ self.frame.forward < 0
        weights = np.concatenate([self.samples.flux, self.samples.area[:, None]], axis=1)
        grids = []
        for side in (True, False):
            chosen = np.flatnonzero(facing == side)
            grid = np.zeros((self.n_layers, 4) + self.grid_shape, dtype=np.float32)
            _splat(np.ascontiguousarray(self._view[chosen]), np.ascontiguousarray(weights[chosen]), self.x0, self.y0,
                   self.cell, self.z0, self.dz, self.n_layers, False, grid)
            grids.append(grid)
        return grids

    def _nearby_irradiance(self, view, normals):
        """``E_q`` at points in view coordinates: the area-weighted irradiance of the samples around each point on
        its side of the surface (facing the camera or away, so the two sides of a thin part do not mix), read from
        the layer grid as ``M`` is."""
        facing = normals @ self.frame.forward < 0
        out = np.zeros((len(view), 3))
        for side, grid in zip((True, False), self._irradiance_grids):
            chosen = np.flatnonzero(facing == side)
            if len(chosen) == 0:
                continue
            sums = np.empty((len(chosen), 4))
            _lookup(np.ascontiguousarray(view[chosen]), self.x0, self.y0, self.cell, self.z0, self.dz, self.n_layers,
                    grid, sums)
            area = sums[:, 3:4]
            out[chosen] = np.divide(sums[:, :3], area, out=np.zeros((len(chosen), 3)), where=area > 0)
        return out

    def layer_image(self, layer):
        """The exitance image ``M_l`` (3, H, W) of one layer, computing it if needed.

        Parameters
        ----------
        layer : int
            The layer index, ``0 .. n_layers - 1`` (at depth ``z0 + layer dz``, mm).

        Returns
        -------
        numpy.ndarray, shape (3, H, W), float32
            A copy of ``M_l`` per RGB channel (the irradiance's unit), on the grid of ``grid_shape = (H, W)`` cells
            of ``cell`` mm.
        """
        self.compute_layers([layer])
        return self._exitance_layers[layer].copy()

    @property
    def pairs_per_layer(self):
        """For every layer, how many non-empty source layers it convolves (max over channels): the paper's ``c``.

        An int64 array of shape (n_layers,)."""
        distance = np.abs(self.source_layers[None, :] - np.arange(self.n_layers)[:, None])
        return self.keep[distance].sum(axis=1).max(axis=1)

    @property
    def stats(self):
        stats = super().stats
        stats.update({
            "layers": self.n_layers,
            "grid_shape": list(self.grid_shape),
            "fft_shape": list(self.padded_shape),
            "cell_size_mm": self.cell,
            "downsample": self.downsample,
            "threshold": self.threshold,
            "splat": self.splat,
            "correction": self.correction,
            "layer_depths_mm": (self.z0 + self.dz * np.arange(self.n_layers)).tolist(),
            "dz_mm": self.dz,
            "kernel_reach_cells": list(self.reach),
            "pairs_per_layer": self.pairs_per_layer.tolist(),
            "convolutions_per_layer": float(self.pairs_per_layer.mean()),
            "source_layers": self.source_layers.tolist(),
            "layers_computed": np.flatnonzero(self.computed).tolist(),
            "forward_ffts": len(self.source_layers),
            "inverse_ffts": int(self.computed.sum()),
            "kernels_cached": bool(self.kernels_cached),
            "kernel_energy": self.kernel_energy.tolist(),
            "memory_bytes": self.memory_bytes,
        })
        return stats


register_transport(ConvolutionTransport)
