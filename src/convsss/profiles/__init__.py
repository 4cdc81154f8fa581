"""Radial diffusion profiles ``R_d(r)``: the material's response to a unit point flux (paper Eq. 1).

Units: ``r`` in mm, ``R_d`` in 1/mm^2 per RGB channel, so ``∫ 2 pi r R_d(r) dr`` (the total diffuse reflectance) is
dimensionless. Every profile answers the same questions, which size the convolution kernels later:

- ``profile(r)`` -> array of shape ``r.shape + (3,)``;
- ``total_reflectance`` -> ``∫_0^inf 2 pi r R_d(r) dr`` per channel;
- ``energy_within(radius)`` -> ``∫_0^radius 2 pi r R_d(r) dr``;
- ``radius_below(t)`` -> smallest r with ``R_d(r) <= t R_d(0)`` (the paper's threshold distance ``d_t``, Eq. 8);
- ``radius_energy(f)`` -> smallest r that holds all but a fraction ``f`` of the total;
- ``effective_area()`` -> ``(∫ R_d dA)^2 / ∫ R_d^2 dA``, the area the profile averages over (sizes the samples).

Models (:data:`PROFILE_MODELS`, chosen per object by the renderer's ``profile`` parameter): the classic dipole of
Jensen et al. 2001 (the paper's choice, here), the better dipole (d'Eon 2012, :mod:`.better_dipole`), photon beam
diffusion with single scattering (Habel et al. 2013, :mod:`.beam_diffusion`), Christensen & Burley 2015
(:mod:`.burley`), and a tabulated profile given by the user (the paper's "arbitrary diffusion profiles").
:mod:`.slab` is their ground truth: a light tracer of the path-traced semi-infinite slab.

Normalization (the one statement for every model). The renderer computes paper Eq. 2,
``E = ∫ F_t(eta, w_i) L_i cos dw_i`` (the flux that enters), Eq. 1, ``M(x_o) = ∫ R_d(|x_o - x_i|) E(x_i) dA``, and
Eq. 7, ``L_o = (1/pi) F_t(eta, w_o) M``. The exitance that Eq. 7 sends out is ``∫ L_o cos dw_o = T_d(eta) M`` with
``T_d = 1 - 2 ∫_0^1 F_r(eta, mu) mu dmu`` (:func:`~convsss.fresnel.diffuse_transmittance`). So a model whose physics
gives the exitance ``M_phys(r)`` that leaves the surface per unit flux that entered (the better dipole's and photon
beam diffusion's ``c_phi phi + c_E E_n``, Christensen–Burley's fit, the Monte Carlo tally) enters Eq. 1 as
``R_d(r) = M_phys(r) / T_d(eta)``: energy is conserved through Eq. 2, 1 and 7, and ``total_reflectance`` is the
slab's albedo over ``T_d``. pbrt writes the same BSSRDF as ``(1 - F_r(cos_o)) S_p(r) S_w(w_i)`` with
``S_w = (1 - F_r(cos_i)) / (pi c)``, ``c = 1 - 2 C_1``: the ``1/c`` there is our ``1/T_d`` moved to the entry side.
The classic dipole keeps the paper's ``R_d`` (the flux ``E_n`` alone, with ``alpha'``), unchanged.
"""

import csv
import itertools
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator

from ..errors import ConvsssError
from ..fresnel import diffuse_fresnel_reflectance

#: The most data rows a profile file may have (a plot or a render of a million took minutes; 10 000 resolve any
#: profile to well below its noise).
MAX_PROFILE_ROWS = 100_000
#: The largest radius a tabulated profile may reach, in mm (a kilometre: no medium diffuses light farther; 1e300
#: overflowed the energy integrals and the plots).
MAX_RADIUS_MM = 1e6
CHANNELS = "RGB"
#: :meth:`Profile.effective_area` cuts the profile's peak at the radius holding this fraction of its energy.
PEAK_ENERGY = 0.02


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
        fit: 4-7 times smaller areas uncut, where their measured noise is that of a 2 times smaller one), from
        asking for samples the noise does not need; it changes the dipole's area by about 2 %. Integrated on
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
        total = self.total_reflectance
        hi = self._search_range()
        if f == 0.0:
            return hi
        # energy_within increases; bisect on its negation, which decreases.
        def deficit(r):
            return -np.diagonal(self.energy_within(r))

        return _bisect_decreasing(deficit, -(1.0 - f) * total, np.zeros(3), hi)


class DipoleProfile(Profile):
    """Classic dipole of Jensen, Marschner, Levoy, Hanrahan 2001 (their Eq. 4), with the reduced-albedo factor.

    ``R_d(r) = alpha'/(4 pi) [ z_r (1 + sigma_tr d_r) e^{-sigma_tr d_r} / d_r^3
    + z_v (1 + sigma_tr d_v) e^{-sigma_tr d_v} / d_v^3 ]``
    with ``sigma_t' = sigma_a + sigma_s'``, ``alpha' = sigma_s'/sigma_t'``, ``sigma_tr = sqrt(3 sigma_a sigma_t')``,
    ``z_r = 1/sigma_t'``, ``z_v = z_r (1 + 4A/3)``, ``A = (1 + F_dr)/(1 - F_dr)``, ``d = sqrt(r^2 + z^2)``.
    ``sigma_a = 0`` (no absorption) is allowed: then ``sigma_tr = 0`` and the profile decays as ``r^-3``.
    """

    def __init__(self, sigma_s_prime, sigma_a, eta):
        self.sigma_s_prime = np.broadcast_to(np.asarray(sigma_s_prime, dtype=np.float64), (3,)).copy()
        self.sigma_a = np.broadcast_to(np.asarray(sigma_a, dtype=np.float64), (3,)).copy()
        self.eta = float(eta)
        sigma_t_prime = self.sigma_a + self.sigma_s_prime
        if np.any(sigma_t_prime <= 0):
            raise ConvsssError("a dipole needs sigma_a + sigma_s' > 0 in every channel")
        self.alpha_prime = self.sigma_s_prime / sigma_t_prime
        self.sigma_tr = np.sqrt(3.0 * self.sigma_a * sigma_t_prime)
        f_dr = diffuse_fresnel_reflectance(self.eta)
        self.A = (1.0 + f_dr) / (1.0 - f_dr)
        self.z_r = 1.0 / sigma_t_prime
        self.z_v = self.z_r * (1.0 + 4.0 * self.A / 3.0)

    def __repr__(self):
        return (f"DipoleProfile(sigma_s_prime={self.sigma_s_prime.tolist()}, sigma_a={self.sigma_a.tolist()}, "
                f"eta={self.eta})")

    def __call__(self, r):
        r2 = np.square(np.asarray(r, dtype=np.float64))[..., None]
        d_r = np.sqrt(r2 + self.z_r**2)
        d_v = np.sqrt(r2 + self.z_v**2)
        real = self.z_r * (1.0 + self.sigma_tr * d_r) * np.exp(-self.sigma_tr * d_r) / d_r**3
        virtual = self.z_v * (1.0 + self.sigma_tr * d_v) * np.exp(-self.sigma_tr * d_v) / d_v**3
        return self.alpha_prime / (4.0 * np.pi) * (real + virtual)

    def energy_within(self, radius):
        """Closed form: ``alpha'/2 sum_{z in z_r, z_v} (e^{-sigma_tr z} - z e^{-sigma_tr d}/d)``, ``d = sqrt(R^2+z^2)``.

        It follows from ``d/dd [-e^{-s d}/d] = (1 + s d) e^{-s d}/d^2`` and ``r dr = d dd``.
        """
        r2 = np.square(np.asarray(radius, dtype=np.float64))[..., None]
        total = 0.0
        for z in (self.z_r, self.z_v):
            d = np.sqrt(r2 + z**2)
            with np.errstate(invalid="ignore"):
                inner = np.where(np.isinf(d), 0.0, z * np.exp(-self.sigma_tr * d) / d)
            total = total + np.exp(-self.sigma_tr * z) - inner
        return 0.5 * self.alpha_prime * total

    @property
    def total_reflectance(self):
        """Closed form ``alpha'/2 (1 + e^{-4/3 A sqrt(3(1-alpha'))}) e^{-sqrt(3(1-alpha'))}`` (Jensen et al. 2001)."""
        s = np.sqrt(3.0 * (1.0 - self.alpha_prime))
        return 0.5 * self.alpha_prime * (1.0 + np.exp(-4.0 / 3.0 * self.A * s)) * np.exp(-s)


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


class TabulatedProfile(Profile):
    """A profile given as samples ``R_d(r_k)`` per channel: the paper's user-defined diffusion profiles.

    Between samples the profile is interpolated in log space by a monotone cubic (PCHIP on ``log R_d``), so it stays
    smooth, positive and non-increasing; from the last positive sample to a following zero sample it falls linearly
    to zero. Before the first radius it is constant, past the last radius it is zero (``support``).

    Parameters
    ----------
    r_mm : array_like, shape (n,)
        Radii in mm: finite, >= 0, strictly increasing, n >= 2.
    values : array_like, shape (n, 3) or (n,)
        ``R_d`` in 1/mm^2: finite, >= 0, non-increasing with r in every channel, positive at the first radius.
    """

    def __init__(self, r_mm, values, name="tabulated"):
        r = np.asarray(r_mm, dtype=np.float64)
        v = np.asarray(values, dtype=np.float64)
        if v.ndim == 1:
            v = np.repeat(v[:, None], 3, axis=1)
        self.name = name
        self._check(r, v)
        self.r, self.values = r, v
        self.support = float(r[-1])
        self._curves = []
        for c in range(3):
            positive = v[:, c] > 0
            n_pos = int(positive.sum())
            log_curve = PchipInterpolator(r[:n_pos], np.log(v[:n_pos, c])) if n_pos >= 2 else None
            self._curves.append((n_pos, log_curve))
        self._build_energy_table()

    @staticmethod
    def _check(r, v):
        if r.ndim != 1 or len(r) < 2:
            raise ConvsssError(f"tabulated profile needs at least 2 radii in a 1-D list, got shape {r.shape}")
        if v.shape != (len(r), 3):
            raise ConvsssError(f"tabulated profile values have shape {v.shape}: expected ({len(r)}, 3) or ({len(r)},)")
        bad = ~np.isfinite(r) | (r < 0) | (r > MAX_RADIUS_MM)
        if bad.any():
            raise ConvsssError(f"tabulated profile radius r={float(r[bad][0])!r} is not allowed: "
                               f"radii are in mm, finite, from 0 to {MAX_RADIUS_MM:g}")
        step = np.diff(r)
        if np.any(step <= 0):
            k = int(np.argmax(step <= 0))
            raise ConvsssError(f"tabulated profile radii must strictly increase: r={float(r[k])!r} "
                               f"is followed by {float(r[k + 1])!r}")
        for c in range(3):
            col = v[:, c]
            bad = ~np.isfinite(col) | (col < 0)
            if bad.any():
                k = int(np.argmax(bad))
                raise ConvsssError(f"tabulated profile value {float(col[k])!r} at r={float(r[k])!r} mm, "
                                   f"channel {CHANNELS[c]}, is not allowed: values must be finite and >= 0")
            rise = np.diff(col) > 0
            if rise.any():
                k = int(np.argmax(rise))
                raise ConvsssError(f"tabulated profile increases in channel {CHANNELS[c]} from {float(col[k])!r} "
                                   f"at r={float(r[k])!r} mm to {float(col[k + 1])!r} at r={float(r[k + 1])!r} mm: "
                                   "a diffusion profile must not increase with r")
            if col[0] <= 0:
                raise ConvsssError(f"tabulated profile is zero at its first radius in channel {CHANNELS[c]}: "
                                   "R_d must be positive at the smallest radius")

    @classmethod
    def from_csv(cls, path):
        """Read a CSV with a header and the columns ``r_mm, R, G, B`` (one row per radius).

        Parameters
        ----------
        path : str or Path
            A text file: the header ``r_mm,R,G,B``, then at least 2 rows of 4 numbers (more columns are ignored).

        Returns
        -------
        TabulatedProfile

        Raises
        ------
        ConvsssError
            In one line, when the file is missing, not a text CSV, has a row of fewer than 4 columns, a value that
            is not a number, or fewer than 2 rows of data (and for every check of the profile itself).
        """
        path = Path(path)
        if not path.is_file():
            raise ConvsssError(f"profile file {str(path)!r} does not exist")
        try:
            with path.open(newline="", encoding="utf-8") as f:
                rows = [row for row in itertools.islice(csv.reader(f), MAX_PROFILE_ROWS + 2) if row]
            if len(rows) > MAX_PROFILE_ROWS + 1:
                raise ConvsssError(f"profile file {str(path)!r} has more than {MAX_PROFILE_ROWS} rows: a radial "
                                   "profile needs a few thousand (resample it, e.g. every 1 % in r)")
        except (UnicodeDecodeError, csv.Error) as e:
            raise ConvsssError(f"profile file {str(path)!r} is not a CSV (text with the columns r_mm, R, G, B): "
                               f"{' '.join(str(e).split())}") from None
        for k, row in enumerate(rows):
            if len(row) < 4:
                raise ConvsssError(f"profile file {str(path)!r} line {k + 1} has {len(row)} columns: "
                                   "a profile needs 4 columns r_mm, R, G, B")
        header = [h.strip().lower() for h in rows[0]] if rows else []
        if header[:4] != ["r_mm", "r", "g", "b"]:
            got = rows[0] if rows else "nothing"
            raise ConvsssError(f"profile file {str(path)!r} must start with the header 'r_mm,R,G,B', got {got}")
        try:
            table = np.array([[float(x) for x in row[:4]] for row in rows[1:]], dtype=np.float64).reshape(-1, 4)
        except ValueError as e:
            raise ConvsssError(f"profile file {str(path)!r} has a value that is not a number: {e}") from None
        if table.shape[0] < 2:
            raise ConvsssError(f"profile file {str(path)!r} needs at least 2 rows of data")
        return cls(table[:, 0], table[:, 1:4], name=path.name)

    def __repr__(self):
        return f"TabulatedProfile({self.name!r}, {len(self.r)} radii up to {self.support} mm)"

    def __call__(self, r):
        r = np.clip(np.asarray(r, dtype=np.float64), self.r[0], None)
        out = np.zeros(r.shape + (3,))
        for c, (n_pos, log_curve) in enumerate(self._curves):
            r_last = self.r[n_pos - 1]
            inside = r <= r_last
            if log_curve is not None:
                out[..., c] = np.where(inside, np.exp(log_curve(np.minimum(r, r_last))), 0.0)
            else:
                out[..., c] = np.where(inside, self.values[0, c], 0.0)
            if n_pos < len(self.r):  # linear fall to the first zero sample
                r_zero = self.r[n_pos]
                ramp = (r > r_last) & (r < r_zero)
                out[..., c] += np.where(ramp, self.values[n_pos - 1, c] * (r_zero - r) / (r_zero - r_last), 0.0)
        return out

    def _build_energy_table(self, per_interval=64):
        """Cumulative ``∫ 2 pi r R_d dr`` on a fine grid (``per_interval`` points between samples, plus [0, r_0])."""
        edges = np.concatenate([[0.0], self.r]) if self.r[0] > 0 else self.r
        t = np.linspace(0.0, 1.0, per_interval + 1)[:-1]
        grid = np.concatenate([a + (b - a) * t for a, b in zip(edges[:-1], edges[1:])] + [[edges[-1]]])
        integrand = 2.0 * np.pi * grid[:, None] * self(grid)
        steps = 0.5 * (integrand[1:] + integrand[:-1]) * np.diff(grid)[:, None]
        self._energy_r = grid
        self._energy = np.concatenate([np.zeros((1, 3)), np.cumsum(steps, axis=0)])

    def energy_within(self, radius):
        radius = np.asarray(radius, dtype=np.float64)
        return np.stack([np.interp(radius, self._energy_r, self._energy[:, c]) for c in range(3)], axis=-1)

    @property
    def total_reflectance(self):
        return self._energy[-1].copy()


# The models register here (they import the base classes above).
from .beam_diffusion import BeamDiffusionProfile  # noqa: E402
from .better_dipole import BetterDipoleProfile  # noqa: E402
from .burley import BurleyProfile  # noqa: E402
from .models import (  # noqa: E402
    DEFAULT_PROFILE,
    PROFILE_MODELS,
    material_from_color,
    model_profile,
    parse_profile_spec,
    resolve_profile,
)

__all__ = ["CHANNELS", "DEFAULT_PROFILE", "PROFILE_MODELS", "BeamDiffusionProfile", "BetterDipoleProfile",
           "BurleyProfile", "DipoleProfile", "Profile", "ScaledProfile", "TabulatedProfile", "material_from_color",
           "model_profile", "parse_profile_spec", "resolve_profile"]
