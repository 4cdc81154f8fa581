"""The profile split by distance (Eq. M1, M2): the core, middle bands and far field, and the lengths one ``accuracy``
sets (:mod:`convsss.transport.multiscale`)."""

import math
from dataclasses import dataclass

import numpy as np

from ...errors import ConvsssError

#: Entries of the core and middle-band tables, uniform in ``r^2``.
BAND_TABLE = 4096


#: The far kernel is cut where all but this fraction of the profile's energy is held.
FAR_TAIL = 1e-5


#: The local limit's scale: the lengths follow ``max(w, LOCAL_SCALE f)`` for a pixel footprint ``f`` (Eq. M3), so
#: ``r_0 = f``. (Chosen against the resolved sum, whose means per channel it keeps slightly low; at ``f / 2`` they
#: spread further.)
LOCAL_SCALE = 1.0 / 3.0


#: A far field holding less than this share of ``accuracy`` of every channel's energy is dropped.
FAR_SKIP = 0.1


#: Middle bands at most (each doubles the far mesh's spacing).
MAX_LEVELS = 24


def core_width(profile):
    """The profile's core width ``w`` in mm: the smallest radius, over the channels where it is not zero, where
    ``R_d`` falls to half its peak (a profile with an infinite peak uses a quarter of its half-energy radius; one
    that is zero in every channel, 1 mm: it has nothing to resolve)."""
    peak = np.asarray(profile(0.0), dtype=np.float64)
    live = peak > 0
    if not live.any():
        return 1.0
    if np.all(np.isfinite(peak)):
        w = float(np.min(np.asarray(profile.radius_below(0.5))[live]))
    else:
        w = 0.25 * float(np.min(np.asarray(profile.radius_energy(0.5))[live]))
    if not math.isfinite(w) or w <= 0:
        raise ConvsssError("multiscale transport: the profile has no finite core width")
    return w


def far_reach(profile):
    """Per channel, the radius holding all but :data:`FAR_TAIL` of the profile's energy (0 where it is zero)."""
    live = np.asarray(profile(0.0), dtype=np.float64) > 0
    return np.where(live, np.asarray(profile.radius_energy(FAR_TAIL), dtype=np.float64), 0.0)


@dataclass(frozen=True)
class Scales:
    """The lengths of the multi-scale transport in mm: cluster side ``s`` of the core sums, that of the first middle
    band, core radius ``r_0``, voxel side ``g`` of the first band, split radius ``r_c`` and far mesh spacing ``h``;
    ``levels`` the middle bands ``L`` between ``r_0`` and ``r_c = 2^L r_0`` (:meth:`band`); ``local`` where the
    lengths follow the pixel footprint rather than the profile (Eq. M3)."""

    cluster: float
    band_cluster: float
    core: float
    voxel: float
    split: float
    mesh: float
    levels: int = 1
    local: bool = False

    @property
    def radii(self):
        """``r_0 < r_1 < ... < r_L = r_c``, each twice the last."""
        return tuple(self.core * 2**k for k in range(self.levels + 1))

    def band(self, k):
        """Middle band ``k`` (1 to ``levels``): its outer radius ``r_k``, cluster side and voxel side, each ``2^(k-1)``
        times the first band's."""
        return self.core * 2**k, self.band_cluster * 2 ** (k - 1), self.voxel * 2 ** (k - 1)


def scales(profile, accuracy, cell_size=None, levels=1):
    """The :class:`Scales` for ``accuracy`` from the profile's core width ``w`` (:func:`core_width`), or from
    ``LOCAL_SCALE`` times the pixel footprint ``cell_size`` (mm) where that is larger (the local limit, Eq. M3), with
    ``levels`` middle bands.

    The errors are second order in the cluster sides, the voxel side and the mesh spacing relative to the profile's
    features, so these grow as ``sqrt(accuracy)``: ``s = w k``, ``2 s`` for the middle band (smooth at ``r_0``, it
    needs no finer sources: on the benchmark scenes the default's mean error grows a little and the band's corner
    sums get much cheaper), ``g = 0.75 w k``, ``h = 2.5 w k`` with ``k = sqrt(accuracy / 0.01)``; the split radii
    stay at ``r_0 = 3 w`` and ``r_c = 6 w``. (The far field's quadratic B-splines, against trilinear tents at
    ``h = 2 w k``: a lower mean error on all five benchmark scenes, with half the mesh cells.) The factors were
    chosen by measurement against the exact sum (``convsss bench accuracy``) to stay below ``accuracy`` on renders.
    Each further band doubles ``r_c`` and ``h`` (the far field is smooth at ``r_c``): band ``k`` is smooth at
    ``r_{k-1}`` and is summed as the first is at twice the lengths of the band before it.
    """
    w = core_width(profile)
    local = cell_size is not None and LOCAL_SCALE * cell_size > w
    w = LOCAL_SCALE * cell_size if local else w
    grow = math.sqrt(accuracy / 0.01)
    wide = 2 ** (levels - 1)
    return Scales(cluster=w * grow, band_cluster=2.0 * w * grow, core=3.0 * w, voxel=0.75 * w * grow,
                  split=6.0 * w * wide, mesh=2.5 * w * grow * wide, levels=levels, local=local)


def cap(fn, r):
    """Eq. M1: ``(a, b)`` per channel, shape (3,) each, with ``a + b r^2`` matching ``fn`` (radii -> (..., 3)) in
    value and slope at ``r``."""
    step = 1e-4 * r
    value = np.asarray(fn(np.float64(r)), dtype=np.float64)
    slope = (np.asarray(fn(np.float64(r + step))) - np.asarray(fn(np.float64(r - step)))) / (2 * step)
    b = slope / (2 * r)
    return value - b * r * r, b


def split(profile, radii, local=False):
    """Eq. M2 over the radii ``r_0 < ... < r_L = r_c`` (:attr:`Scales.radii`): the far cap ``(a, b)``, the core table
    (BAND_TABLE, 3) uniform in ``r^2`` on ``[0, r_0^2]``, and the ``L`` middle bands' tables, band ``k`` on
    ``[0, r_k^2]`` (the residual less the caps beyond ``r_{k-1}``, its cap inside), each table's last entry 0;
    ``local``: the core as its energy over the smooth kernel of Eq. M3."""
    caps = [cap(profile, radii[-1])]  # the far cap, then each band's, outermost first

    def residual(r, caps):  # R_d less the caps, inside the innermost of their radii
        r = np.asarray(r, dtype=np.float64)
        out = np.asarray(profile(r), dtype=np.float64)
        for a, b in caps:
            out = out - (a + b * r[..., None] ** 2)
        return out

    bands = []
    for outer, inner in zip(radii[:0:-1], radii[-2::-1]):
        held = list(caps)
        caps.append(cap(lambda r, held=held: residual(r, held), inner))
        r2 = np.linspace(0.0, outer * outer, BAND_TABLE)[:, None]
        band = np.where(r2 < inner * inner, caps[-1][0] + caps[-1][1] * r2, residual(np.sqrt(r2[:, 0]), held))
        band[-1] = 0.0
        bands.insert(0, np.ascontiguousarray(band))
    r_0 = radii[0]
    r2 = np.linspace(0.0, r_0 * r_0, BAND_TABLE)[:, None]
    if local:
        # Eq. M3: E_core = the energy within r_0 less the caps' there (∫ 2 pi r (a + b r^2) dr = pi (a r^2 + b r^4/2)).
        held = sum(a * r_0**2 + 0.5 * b * r_0**4 for a, b in caps)
        energy = np.asarray(profile.energy_within(r_0), dtype=np.float64) - np.pi * held
        core = energy * 3.0 / (np.pi * r_0**2) * (1.0 - r2 / r_0**2) ** 2
    else:
        core = residual(np.sqrt(r2[:, 0]), caps)
    core[-1] = 0.0
    return caps[0], np.ascontiguousarray(core), bands


def far_energy(profile, r_c, far):
    """Per channel, the share of the profile's energy that its far field ``R_far`` (Eq. M2, cap ``far``) holds."""
    inner = np.pi * (far[0] * r_c**2 + 0.5 * far[1] * r_c**4)
    total = np.asarray(profile.total_reflectance, dtype=np.float64)
    outer = total - np.asarray(profile.energy_within(r_c), dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(total > 0, (inner + outer) / np.where(total > 0, total, 1.0), 0.0)


def summed_area(profile, radii, far, core, bands):
    """The effective area (:meth:`~convsss.profiles.Profile.effective_area`, uncut: the tables have no singular
    peak) of the profile as the bands sum it, ``(∫ R dA)^2 / ∫ R^2 dA`` per channel (mm^2, shape (3,)), for the
    ``far`` cap and the ``core`` and ``bands`` tables of :func:`split` over ``radii``: with the core of Eq. M3, it
    grows as the pixel footprint squared."""
    u = np.linspace(0.0, radii[-1] ** 2, BAND_TABLE)
    inner = far[0] + far[1] * u[:, None]
    for radius, table in zip(radii, [core, *bands]):
        inner = inner + np.stack([np.interp(u, np.linspace(0.0, radius**2, BAND_TABLE), table[:, c], right=0.0)
                                  for c in range(3)], axis=1)
    second = np.pi * np.trapezoid(inner**2, u, axis=0)  # dA = pi d(r^2)
    r_scale, ds, values = profile.radial_table()
    r = r_scale * np.expm1(ds * np.arange(len(values)))
    out = r >= radii[-1]
    second += np.trapezoid(2.0 * np.pi * r[out, None] * values[out] ** 2, r[out], axis=0)
    total = np.asarray(profile.total_reflectance, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(second > 0, total * total / np.where(second > 0, second, 1.0), np.inf)
