"""Ground truth for profiles: the radial exitance of a semi-infinite slab lit by a narrow beam at normal incidence.

A light tracer of the very medium Mitsuba's ``volpathmis`` renders (a homogeneous, isotropically scattering medium
with the reduced coefficients, behind a smooth dielectric of relative index ``eta``): each photon enters at the
origin along the inward normal (or at a slant: :mod:`~convsss.profiles.incidence`) carrying the transmitted flux
(Eq. 2's ``F_t(eta, w_i)`` is outside the profile),
flies exponential distances, scatters isotropically with weight ``alpha'`` per collision (Russian roulette below
1 %), and at the boundary is reflected with the Fresnel probability ``F_r(1/eta, cos)`` or leaves; a photon that
leaves is tallied at its radius (the radial exitance histogram). Optical units (``sigma_t' = 1``) inside, so one
walk serves every material of the same ``(alpha', eta)``; :func:`slab_profile` scales to mm.

Normalization (one place for every model, :mod:`convsss.profiles`): paper Eq. 1 and 7 send
``(1/pi) F_t(eta, w_o) M`` out, whose hemispherical integral is ``T_d(eta) M`` (:func:`~convsss.fresnel.
diffuse_transmittance`); so the measured profile is the exitance per unit transmitted flux divided by ``T_d``:
``R(r) = W(r) / (N dA T_d)``. Its total ``sum W / (N T_d)`` is the slab's total reflectance in the same sense.

Why a tally instead of a camera: a camera path reaches a narrow beam through a smooth dielectric only by chance, and
a point or directional light not at all (``shared/notes/mitsuba3.md``). The tally is checked against
``volpathmis`` on the same material in a Mitsuba box (:func:`convsss.pipeline.reference.volpath_slab_albedo`,
``tests/profiles/test_slab.py``): by reciprocity, a radiance meter looking straight down at a slab under a uniform sky
of radiance 1 reads the slab's albedo at normal incidence, ``F_r(eta, 1) + F_t(eta, 1) sum W / N``, and, with a black
disk of radius ``r_1`` just above the surface, ``F_t(eta, 1) sum_{r > r_1} W / N``: the tally's radial distribution,
through Mitsuba.
"""

import numpy as np

from ..errors import ConvsssError
from ..fresnel import check_eta, diffuse_transmittance, fresnel_reflectance
from ..jit import njit, prange
from ..splitmix import isotropic, mix, uniform

#: Fresnel table resolution in cos (the walk looks ``F_r`` up instead of carrying a second Fresnel formula).
FRESNEL_TABLE = 4097
#: Bins per decade of optical radius; the first bin edge past 0.
BINS_PER_DECADE = 20
R_FIRST = 1e-3


@njit(parallel=True, fastmath=False, cache=True)
def _walk(photons, chunks, albedo, fresnel, depth_max, edges, seed, incidence):
    """Photons enter at the origin at cosine ``incidence`` to the inward normal. Per chunk: (weight, weight^2,
    single-scattered weight) per radial bin (last bin: past the edges), and the weight lost through the bottom."""
    n_bins = len(edges)
    hist = np.zeros((chunks, 3, n_bins))
    lost = np.zeros(chunks)
    per_chunk = (photons + chunks - 1) // chunks
    log_first = np.log(edges[1])
    per_log = (n_bins - 2) / (np.log(edges[-1]) - log_first)
    table_n = len(fresnel) - 1
    for c in prange(chunks):
        start = c * per_chunk
        stop = min(photons, start + per_chunk)
        for i in range(start, stop):
            # each photon's stream starts at a hash of (seed, photon): streams are independent of the thread count
            state = mix(mix(np.uint64(seed) + np.uint64(0x5851F42D4C957F2D)) + np.uint64(i))
            x = y = z = 0.0
            ux = np.sqrt(max(0.0, 1.0 - incidence * incidence))
            uy = 0.0
            uz = incidence
            w = 1.0
            scatters = 0
            while True:
                state, u = uniform(state)
                s = -np.log(u)
                if uz < 0.0 and s >= z / -uz:  # reaches the boundary z = 0
                    t = z / -uz
                    x += t * ux
                    y += t * uy
                    z = 0.0
                    f = -uz * table_n
                    k = min(int(f), table_n - 1)
                    fr = fresnel[k] + (f - k) * (fresnel[k + 1] - fresnel[k])
                    state, u = uniform(state)
                    if u < fr:
                        uz = -uz
                        continue
                    r = np.sqrt(x * x + y * y)
                    if r < edges[1]:
                        b = 0
                    elif r >= edges[-1]:
                        b = n_bins - 1
                    else:
                        b = min(1 + int((np.log(r) - log_first) * per_log), n_bins - 2)
                    hist[c, 0, b] += w
                    hist[c, 1, b] += w * w
                    if scatters == 1:
                        hist[c, 2, b] += w
                    break
                x += s * ux
                y += s * uy
                z += s * uz
                if z > depth_max:
                    lost[c] += w
                    break
                w *= albedo
                scatters += 1
                if w < 0.01:
                    state, u = uniform(state)
                    if u >= 0.1:
                        break
                    w *= 10.0
                state, ux, uy, uz = isotropic(state)
    return hist, lost


def radial_edges(r_max):
    """Bin edges in optical radius: 0, then :data:`BINS_PER_DECADE` per decade from :data:`R_FIRST` to ``r_max``."""
    decades = np.log10(r_max / R_FIRST)
    n = max(2, int(np.ceil(decades * BINS_PER_DECADE)))
    return np.concatenate([[0.0], R_FIRST * np.power(10.0, np.linspace(0.0, decades, n + 1))])


def slab_extent(albedo):
    """``(depth_max, r_max)`` in mean free paths: 30 diffusion lengths (at least 50 mfp), at most 2000 mfp."""
    albedo = float(albedo)
    sigma_tr = np.sqrt(3.0 * (1.0 - albedo))  # optical units: sigma_t' = 1
    reach = 2000.0 if sigma_tr == 0 else float(np.clip(30.0 / sigma_tr, 50.0, 2000.0))
    return reach, reach


def slab_tally(albedo, eta, photons=1 << 20, seed=0, incidence=1.0):
    """Radial exitance of a semi-infinite slab of reduced albedo ``albedo`` and index ``eta`` (optical units).

    Parameters
    ----------
    albedo : float
        Reduced single-scattering albedo ``alpha' = sigma_s'/sigma_t'`` in [0, 1].
    eta : float
        Relative index of the boundary (1: index-matched).
    photons : int
        Photons traced (each enters with the transmitted flux 1).
    seed : int
        The same seed gives the same tally, whatever the thread count.
    incidence : float
        Cosine of the beam's direction inside the medium to the inward normal (1: normal incidence, the profiles';
        below 1 the exits are no longer radially symmetric and only the totals are of use:
        :mod:`convsss.profiles.incidence`).

    Returns
    -------
    dict
        ``edges`` (B + 1,) optical radii; ``profile`` (B,) and ``stderr`` (B,): ``R(r)`` per mfp^2 in the
        normalization of Eq. 1 (exitance per unit transmitted flux over ``T_d``); ``single`` (B,): its singly
        scattered part; ``total`` and ``total_stderr``: ``∫ 2 pi r R dr`` with the exits past the last edge;
        ``escaped`` (per transmitted flux, all exits, no ``T_d``), ``lost`` (through the bottom), ``depth_max``.
    """
    albedo = float(albedo)
    if not 0.0 <= albedo <= 1.0:
        raise ConvsssError(f"albedo={albedo!r} is not allowed: it must lie in [0, 1]")
    eta = check_eta(eta)
    photons = int(photons)
    incidence = float(incidence)
    if not 0.0 < incidence <= 1.0:
        raise ConvsssError(f"incidence={incidence!r} is not allowed: it must lie in (0, 1]")
    if photons < 1:
        raise ConvsssError(f"photons={photons!r} is not allowed: it must be >= 1")
    depth_max, r_max = slab_extent(albedo)
    edges = radial_edges(r_max)
    fresnel = fresnel_reflectance(1.0 / eta, np.linspace(0.0, 1.0, FRESNEL_TABLE))
    chunks = 64
    hist, lost = _walk(photons, chunks, albedo, fresnel, depth_max, edges, int(seed), incidence)
    weight, square, single = hist.sum(axis=0)
    # Per-photon variance from the per-bin sums of w and w^2 (each photon lands in at most one bin).
    n = float(photons)
    t_d = diffuse_transmittance(eta)
    area = np.pi * np.diff(edges**2)
    mean = weight[:-1] / n
    var = np.maximum(square[:-1] / n - mean**2, 0.0) / n
    escaped = weight.sum() / n
    escaped_var = max(square.sum() / n - escaped**2, 0.0) / n
    return {
        "albedo": albedo, "eta": eta, "photons": photons, "seed": int(seed), "incidence": incidence,
        "edges": edges,
        "profile": mean / area / t_d,
        "stderr": np.sqrt(var) / area / t_d,
        "single": single[:-1] / n / area / t_d,
        "total": escaped / t_d,
        "total_stderr": float(np.sqrt(escaped_var)) / t_d,
        "escaped": escaped,
        "lost": float(lost.sum()) / n,
        "depth_max": depth_max,
    }


# ---- What the same slab in Mitsuba's volpathmis reads, for checking the tally -----------------------------------

def tally_albedo(material, occluder_mm=0.0, photons=1 << 18, seed=0):
    """The slab's albedo at normal incidence per channel from the tally: ``F_r(eta, 1) + F_t(eta, 1) x`` (the escaped
    flux per transmitted flux); with ``occluder_mm > 0``, only ``F_t(eta, 1) x`` for the flux that leaves beyond that
    radius (what :func:`~convsss.pipeline.reference.volpath_slab_albedo` reads under a black disk). Within a bin the
    exits count as uniform in area."""
    out = np.empty(3)
    specular = float(fresnel_reflectance(material.eta, 1.0))
    for c in range(3):
        t = slab_tally(material.albedo_prime[c], material.eta, photons, seed)
        weights = t["profile"] * np.pi * np.diff(t["edges"] ** 2) * diffuse_transmittance(material.eta)
        if occluder_mm > 0:
            r1 = occluder_mm * material.sigma_t_prime[c]
            inside = np.interp(r1**2, t["edges"] ** 2, np.concatenate([[0.0], np.cumsum(weights)]))
            out[c] = (1.0 - specular) * (t["escaped"] - inside)
        else:
            out[c] = specular + (1.0 - specular) * t["escaped"]
    return out
