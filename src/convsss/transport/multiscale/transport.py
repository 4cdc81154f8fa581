"""The multi-scale transport itself: the profile's pieces summed at the queries
(:mod:`convsss.transport.multiscale`)."""


import numpy as np

from ...memory import check_memory
from ...parameters import Parameter
from ..base import Transport, register_transport
from ..kernels import profile_key
from ..radial import RadialTable
from .cells import BandCorners, CellList, cell_list_bytes
from .clusters import bounds, cube_cells, group, merge, sheet_side
from .far_field import FAR_CELLS, SPECTRA, _deposit, _interpolate, far_bytes, far_mesh, far_spectrum, padded_convolution
from .scales import FAR_SKIP, MAX_LEVELS, far_energy, far_reach, scales, split, summed_area


class MultiscaleTransport(Transport):
    """Core and middle band summed directly over clustered samples, far field on a 3-D mesh by FFT; see the module
    docstring."""

    name = "multiscale"
    parameters = (
        Parameter("accuracy", float, 0.01, "Relative error aimed at by the multiscale transport: sets its cluster "
                  "and voxel sizes, split radii and far-field mesh from the profile's core width.", low=1e-6,
                  high=0.5),
        Parameter("cell_size", float, None, "The pixel footprint in mm where the object is seen (the renderer "
                  "sets it): the profile's features narrower than a third of it are summed as their energy over a "
                  "smooth kernel (the local limit), so that the work follows the image.", low=0.0, low_open=True,
                  exposed=False),
        Parameter("memory_limit", float, None, "Bytes the far-field mesh may use (default: what the machine has "
                  "available).", low=0.0, low_open=True, exposed=False),
    )

    memory_advice = "raise the transport's accuracy (a coarser far-field mesh), or use the hierarchical transport"

    @classmethod
    def _split(cls, profile, params, lo, hi):
        """The :class:`Scales` under ``params`` for samples within ``lo``, ``hi`` (3,) of the view frame, the
        profile's split (:func:`split`) and whether the far field is kept (it holds at least :data:`FAR_SKIP` of the
        accuracy in some channel): as few middle bands as keep the far mesh within :data:`FAR_CELLS` FFT cells (or
        drop its field), one where it fits."""
        accuracy, reach = params.get("accuracy", 0.01), far_reach(profile)
        for levels in range(1, MAX_LEVELS + 1):
            sc = scales(profile, accuracy, params.get("cell_size"), levels)
            parts = split(profile, sc.radii, sc.local)
            kept = bool(np.max(far_energy(profile, sc.split, parts[0])) >= FAR_SKIP * accuracy)
            if not kept or np.prod(np.asarray(far_mesh(sc, reach, lo, hi)[2], dtype=np.float64)) <= FAR_CELLS:
                break
        return sc, parts, kept

    @classmethod
    def planned_bytes(cls, bounds, profile, count, params, material=None):
        """The far-field mesh's spectra and the cell lists' offsets (:func:`far_mesh`, :class:`CellList`)."""
        lo, hi = bounds
        sc, _, kept = cls._split(profile, params, lo, hi)
        held = cell_list_bytes(lo, hi, sc.core)
        held += sum(cell_list_bytes(lo, hi, 0.5 * sc.band(k)[0]) for k in range(1, sc.levels + 1))
        if kept:
            held += far_bytes(far_mesh(sc, far_reach(profile), lo, hi)[2])
        return int(held)

    @classmethod
    def sample_area(cls, profile, params):
        """The smallest effective area of the profile as the bands sum it (:func:`summed_area`, with one middle
        band): the profile's own where it is resolved, growing as the pixel footprint squared in the local limit
        (Eq. M3)."""
        sc = scales(profile, params.get("accuracy", 0.01), params.get("cell_size"))
        if not sc.local:
            return super().sample_area(profile, params)
        return float(np.min(summed_area(profile, sc.radii, *split(profile, sc.radii, sc.local))))

    def __init__(self, samples, profile, frame=None, material=None, **params):
        super().__init__(samples, profile, frame, material, **params)
        with self.timings("clusters"):  # the samples' places: which cluster each falls in, whatever its flux
            self._view = self._to_view(samples.position)
            self._lo, self._hi = bounds(self._view)
        with self.timings("kernels"):
            sc, (self._far_cap, self._core, self._band_tables), self._far_kept = self._split(profile, self.params,
                                                                                             self._lo, self._hi)
            self.scales = sc
        with self.timings("clusters"):
            side = sheet_side(None if samples.normal is None else self._to_view(samples.normal, vectors=True))
            self._fine = group(cube_cells(self._view, self._lo, sc.cluster), side)
            self._groups = [group(self._fine.cells // round(sc.band(k)[1] / sc.cluster), self._fine.side)
                            for k in range(1, sc.levels + 1)]
        self._build()

    def _build(self):
        """Everything that depends on the samples' flux: the clusters' flux and centroids, the cell lists, the far
        field and the middle bands."""
        sc, lo, hi = self.scales, self._lo, self._hi
        with self.timings("clusters"):
            fine = merge(self._fine, self._view, self.samples.area, self.samples.flux)
            coarse = [merge(g, fine.centre, fine.area, fine.flux) for g in self._groups]
            self.clusters = len(fine)
        with self.timings("cell_lists"):
            self._core_cells = CellList(fine.centre, fine.flux, lo, sc.core, sc.core, fine.area if sc.local else None)
            band_cells = [CellList(c.centre, c.flux, lo, sc.band(k)[0], 0.5 * sc.band(k)[0])
                          for k, c in enumerate(coarse, start=1)]
        self._far_field(fine.centre, fine.flux, lo, hi)
        with self.timings("band"):
            self._bands = [BandCorners(cells, table, fine.centre, lo, hi, sc.band(k)[2])
                           for k, (cells, table) in enumerate(zip(band_cells, self._band_tables), start=1)]

    def _relit(self, samples):
        """The same places and clusters with the new samples' flux: only :meth:`_build` runs again."""
        return self._rebuilt(samples)

    def _far_field(self, position, flux, lo, hi):
        """Deposit the clusters' flux on the mesh, convolve with ``R_far`` by 3-D FFTs (Eq. M2), keep the field.

        The mesh reaches ``r_c`` past the samples (queries off the surface within that distance read it; farther
        ones read its border); float32 throughout (the error aimed at is far above its round-off).
        """
        self._field = None
        if not self._far_kept:
            self._mesh_origin, self.fft_shape = lo, None
            return
        h = self.scales.mesh
        reach = far_reach(self.profile)
        lo, shape, fft_shape = far_mesh(self.scales, reach, lo, hi)
        check_memory(far_bytes(fft_shape), "the multiscale far-field mesh and its spectra",
                     "raise the transport's accuracy (a coarser mesh)", self.params["memory_limit"])
        self._mesh_origin, self.fft_shape = lo, fft_shape
        with self.timings("far_kernel"):
            radial = RadialTable.of(self.profile)
            key = (profile_key((radial.r_scale, radial.ds, radial.values)), self.scales.split, h, fft_shape)
            kernel_hat = SPECTRA.get(key)
            if kernel_hat is None:
                kernel_hat = far_spectrum(radial, self.scales.split, *self._far_cap, h, fft_shape, reach)
                SPECTRA.put(key, kernel_hat)
        with self.timings("deposit"):
            grid = np.zeros((3,) + tuple(int(n) for n in shape), dtype=np.float32)
            _deposit(position, flux, lo, h, grid)
        with self.timings("far_fft"):
            self._field = padded_convolution(grid, kernel_hat, fft_shape)

    @property
    def query_batch(self):
        """Query points per call (each sums the clusters within ``r_1``)."""
        return 1 << 17

    def _exitance(self, points):
        view = self._to_view(points)
        out = np.zeros((len(points), 3))
        if self._field is not None:
            with self.timings("far_lookup"):
                _interpolate(view, self._mesh_origin, self.scales.mesh, self._field, out)
        with self.timings("band"):
            for band in self._bands:
                band.add(view, out)
        with self.timings("core_sum"):
            if self.scales.local:  # Eq. M3, E_core from the kernel's peak: K(0) = 3 / (pi r_0^2)
                self._core_cells.add_average(view, self._core[0] * np.pi * self.scales.core**2 / 3.0, out)
            else:
                self._core_cells.add_sum(view, self._core, out)
        return np.maximum(out, 0.0)

    @property
    def stats(self):
        """The base stats plus the lengths chosen, the cluster count and the far-field FFT shape (None where the far
        field is dropped)."""
        return {**super().stats, "scales_mm": dict(vars(self.scales)), "clusters": self.clusters,
                "band_corners": sum(b.count for b in self._bands),
                "fft_shape": None if self.fft_shape is None else list(self.fft_shape)}


register_transport(MultiscaleTransport)
