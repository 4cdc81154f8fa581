"""The interface every radial profile implements, and the registry of the profile models.

A profile answers (lengths in mm, ``R_d`` in 1/mm^2 per RGB channel; the conventions and the normalization are in
:mod:`convsss.profiles`):

- ``profile(r)`` -> array of shape ``r.shape + (3,)``;
- ``total_reflectance`` -> ``∫_0^inf 2 pi r R_d(r) dr`` per channel;
- ``energy_within(radius)``, ``radius_below(t)``, ``radius_energy(f)``, ``effective_area()``.

A *model* is a :class:`Profile` subclass built from a material's coefficients, ``Model(sigma_s_prime, sigma_a,
eta)``, with a ``name`` (what the renderer's ``profile`` parameter accepts), a ``title``, a ``rank`` (its place in
lists) and ``optical_total(albedo, eta)`` (its total reflectance, which does not depend on the mean free path); it
registers itself on its module's last line (:func:`register_profile`) into :data:`PROFILE_MODELS`. A new model is
one file, imported by :mod:`convsss.profiles.models`.
"""

import numpy as np

from ..errors import ConvsssError
from ..materials import CHANNELS  # noqa: F401  (the profiles' channels are the materials')

#: :meth:`Profile.effective_area` cuts the profile's peak at the radius holding this fraction of its energy.
PEAK_ENERGY = 0.02


#: Every profile model by name, ordered by their ``rank`` (where a model is listed: help texts, plots, tables).
PROFILE_MODELS = {}


def register_profile(cls):
    """Make the model ``cls`` (a :class:`Profile` subclass with ``name``, ``title``, ``rank`` and
    ``optical_total``) available by its name; returns it."""
    models = sorted([*(c for c in PROFILE_MODELS.values() if c.name != cls.name), cls], key=lambda c: c.rank)
    PROFILE_MODELS.clear()
    PROFILE_MODELS.update((c.name, c) for c in models)
    return cls


def _bisect_decreasing(fn, target, lo, hi, iterations=200):
    """Per channel, the smallest r in [lo, hi] with ``fn(r) <= target`` for a non-increasing ``fn``.

    ``fn`` maps radii of shape (3,) to values of shape (3,); ``target``, ``lo`` and ``hi`` have shape (3,).
    """
    lo, hi = np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        below = fn(mid) <= target
        hi = np.where(below, mid, hi)
        lo = np.where(below, lo, mid)
    return hi


class Profile:
    """Base class of radial profiles. Subclasses implement ``__call__`` and ``energy_within``.

    ``support`` is the radius past which the profile is zero (``inf`` when it never is).
    """

    support = np.inf

    def __call__(self, r):
        raise NotImplementedError

    def energy_within(self, radius):
        raise NotImplementedError

    @property
    def total_reflectance(self):
        """``∫_0^inf 2 pi r R_d(r) dr`` per channel, shape (3,)."""
        return self.energy_within(np.full(3, self.support))[np.arange(3), np.arange(3)]

    def _search_range(self):
        """An upper radius (3,) for root finding: the support, or a radius doubled until the profile is ~0."""
        if np.isfinite(self.support):
            return np.full(3, self.support)
        hi = np.full(3, 1.0)
        peak = self(0.0)
        for _ in range(200):
            tail = np.diagonal(self(hi))
            done = tail <= 1e-300 + 1e-16 * peak
            if done.all():
                break
            hi = np.where(done, hi, 2.0 * hi)
        return hi

    def radial_table(self, size=16384, energy_tail=1e-7):
        """``R_d`` sampled for compiled lookups: returns ``(r_scale, ds, values)`` with ``values[k]`` (size, 3)
        ``= R_d(r_scale (e^{k ds} - 1))``: uniform steps near 0 (``r_scale`` is 1 % of the half-energy radius),
        geometric in the tail, ending where all but ``energy_tail`` of the energy is held (or at the support).
        Linear interpolation in ``s = log(1 + r/r_scale)`` is accurate to about 1e-5 relative; past the end the
        profile counts as 0.
        """
        r_max = float(np.max(self.radius_energy(energy_tail)))
        r_scale = 0.01 * float(np.min(self.radius_energy(0.5)))  # well inside the profile's core
        ds = np.log1p(r_max / r_scale) / (size - 1)
        r = r_scale * np.expm1(ds * np.arange(size))
        return r_scale, ds, np.ascontiguousarray(self(r))

    def effective_area(self):
        """``A_eff = (∫ R_d dA)^2 / ∫ min(R_d, R_d(r_p))^2 dA`` per channel (mm^2, shape (3,)): the area over which the
        profile averages its sources, ``r_p`` the radius holding the innermost :data:`PEAK_ENERGY` of its energy.

        A sum of Eq. 1 over ``n`` independent random samples per mm^2 has a relative variance ``1 / (n A_eff)`` (without
        the cut); the renderer sizes its samples by it (``profile_samples``). The cut keeps a (nearly) singular peak,
        which holds little energy but would dominate ``∫ R_d^2`` (photon beam diffusion's single scattering, Burley's
        fit: uncut, their areas come out several times smaller than their measured noise justifies), from asking
        for samples the noise does not need; it changes the dipole's area only slightly. Integrated on
        :meth:`radial_table` (trapezoids in ``s``); a channel that is zero everywhere gets ``inf``.
        """
        r_scale, ds, values = self.radial_table()
        k = np.arange(1, len(values))
        weight = 2.0 * np.pi * r_scale**2 * np.expm1(ds * k) * np.exp(ds * k) * ds  # 2 pi r dr/ds, per step
        weight[[0, -1]] *= 0.5
        values = values[1:]
        peak = np.diagonal(np.asarray(self(self.radius_energy(1.0 - PEAK_ENERGY)), dtype=np.float64))
        first = np.einsum("k,kc->c", weight, values)
        second = np.einsum("k,kc->c", weight, np.minimum(values, peak) ** 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(second > 0, first * first / np.where(second > 0, second, 1.0), np.inf)

    def radius_below(self, t):
        """Smallest r with ``R_d(r) <= t R_d(0)`` per channel (paper Eq. 8); the support if never reached."""
        t = float(t)
        if not 0.0 <= t <= 1.0:
            raise ConvsssError(f"threshold t={t!r} is not allowed: it must lie in [0, 1]")
        target = t * self(0.0)
        hi = self._search_range()
        if t == 0.0:
            return hi
        return _bisect_decreasing(lambda r: np.diagonal(self(r)), target, np.zeros(3), hi)

    def radius_energy(self, f):
        """Smallest r with ``energy_within(r) >= (1 - f) total_reflectance`` per channel."""
        f = float(f)
        if not 0.0 <= f <= 1.0:
            raise ConvsssError(f"energy fraction f={f!r} is not allowed: it must lie in [0, 1]")
        known = self.__dict__.setdefault("_radius_energy", {})  # a profile does not change: bisect once per f
        if f not in known:
            known[f] = self._search_range() if f == 0.0 else _bisect_decreasing(
                lambda r: -np.diagonal(self.energy_within(r)),  # energy_within increases: its negation decreases
                -(1.0 - f) * self.total_reflectance, np.zeros(3), self._search_range())
        return known[f].copy()


class ScaledProfile(Profile):
    """A profile's shape with another total reflectance: ``scale * base(r)`` per channel (``scale`` (3,)), e.g. a
    model at the exact half-space total (:func:`~convsss.profiles.models.model_profile`, ``total="exact"``)."""

    def __init__(self, base, scale):
        self.base = base
        self.scale = np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,)).copy()
        self.support = base.support

    def __repr__(self):
        return f"ScaledProfile({self.base!r}, scale={self.scale.tolist()})"

    def __call__(self, r):
        return self.base(r) * self.scale

    def energy_within(self, radius):
        return self.base.energy_within(radius) * self.scale
