"""Local-plane correction of the layered transport (beyond the paper): exact for any uniformly lit plane.

The paper's layers are ``dz`` apart, and a sample between two layers is split between them (linear weights, or half
and half). Where ``dz`` spans many mean free paths this discretization is far from the profile: a face-on surface
midway between two layers couples to itself through ``(K_0 + K_1)/2`` instead of ``K_0`` (too dark, down to half),
and a surface seen edge-on collapses into one layer slab (too bright, several times).

Both errors are *local* and depend only on the receiver's tangent plane: its tilt to the view axis
(``cos_theta = |n . forward|``) and its depth fraction ``w`` between its two layers. So we compute, once per
(profile, ``dz``, splat rule), the layered transport's response ``C(cos_theta, w)`` to an infinite plane through the
receiver with that tilt, under uniform irradiance ``E = 1`` (per true area), relative to the exact response
``R_total``. With the source in-plane coordinates ``(u, v)`` (``u`` along the tilt), the source sits ``u sin_theta``
deeper and ``sqrt((u cos_theta)^2 + v^2)`` away in the image plane, so

    C = 1/R_total sum_a sum_b beta_b(w) ∫ du alpha_a(w + u sin_theta / dz) Lambda(d_ab(u)),
    d_ab(u) = sqrt((u cos_theta)^2 + (|a - b| dz)^2),

with ``alpha`` and ``beta`` the depth weights of source and receiver and ``Lambda(d) = ∫ R_d(sqrt(d^2 + v^2)) dv``
the profile integrated along a line at distance ``d``. With ``E_q`` the area-weighted irradiance of the samples around
the receiver on its side of the surface, a uniformly lit tangent plane would deposit ``P = C R_total E_q`` through the
layers where the exact transport deposits ``R_total E_q``. The corrected exitance is

    M = M_layers + R_total (1 - C) E_q                              where C <= 1,   (plane correction, Eq. P1)
    M = M_layers - min((1 - 1/C) M_layers, R_total (C - 1) E_q)     where C > 1.    (plane correction, Eq. P2)

Where the layers under-estimate (``C <= 1``: a face-on receiver between two layers) the correction adds what they miss
for the plane. Where they over-estimate (``C > 1``: a receiver seen edge-on) it removes the plane's excess, but never
more than the excess share ``1 - 1/C`` of what the layers actually deposited: a receiver whose neighbourhood is less
than the lit plane the table assumes (an object smaller than the profile's reach, a silhouette curving away, a shadow
edge) received less than ``P`` from the layers, and subtracting a plane's worth from it would leave a negative
exitance. So ``M >= M_layers / C >= 0`` wherever ``M_layers >= 0`` (Eq. P2), ``M >= M_layers`` where ``C <= 1``
(Eq. P1), and for the lit plane itself ``M_layers = P``: both give ``M = R_total E_q``.

It is exact for a uniformly lit plane of any orientation at any depth, leaves far-field light (e.g. light through a
thin back-lit part, where ``E_q`` is small) as the layers compute it, and is an approximation where the irradiance
varies within a few mean free paths of the receiver (shadow edges).
"""

import numpy as np

from ..jit import njit, prange
from .kernels import KernelCache

N_COS = 33
N_W = 17


def line_integral_table(profile, reach, size=384, quadrature=384):
    """``Lambda(d) = ∫_{-inf}^{inf} R_d(sqrt(d^2 + v^2)) dv`` on a grid of ``d`` (0 and geometric up to ``reach``).

    Parameters
    ----------
    profile : Profile
    reach : float
        The largest distance ``d`` (mm).
    size : int
        Grid points: 0, then ``size - 1`` geometric from 1e-3 of the profile's half-peak radius (the smallest over
        RGB) to ``reach``.
    quadrature : int
        Quadrature points in ``v`` (dense near 0, to ``reach``).

    Returns
    -------
    d : numpy.ndarray, shape (size,), float64
        The distances (mm).
    values : numpy.ndarray, shape (size, 3), float64
        ``Lambda(d)`` per RGB channel (1/mm).
    """
    core = float(np.min(profile.radius_below(0.5)))
    d = np.concatenate([[0.0], np.geomspace(1e-3 * core, reach, size - 1)])
    # v = core * sinh(t): dense near 0, reaching far into the tail.
    t = np.linspace(0.0, np.arcsinh(reach / (1e-3 * core)), quadrature)
    v = 1e-3 * core * np.sinh(t)
    weight = np.gradient(v)
    values = np.empty((size, 3))
    for start in range(0, size, 128):
        block = d[start:start + 128]
        r = np.sqrt(block[:, None] ** 2 + v[None, :] ** 2)
        values[start:start + 128] = 2.0 * np.einsum("dvc,v->dc", profile(r), weight)
    return d, values


@njit(cache=True)
def _interp(x, grid, values, c):
    if x >= grid[-1]:
        return 0.0
    k = np.searchsorted(grid, x) - 1
    k = max(k, 0)
    f = (x - grid[k]) / (grid[k + 1] - grid[k])
    return (1.0 - f) * values[k, c] + f * values[k + 1, c]


@njit(parallel=True, cache=True)
def _plane_response(cos_grid, w_grid, dz, half, u, du, d_grid, lam, out):
    for i in prange(cos_grid.shape[0]):
        c_theta = cos_grid[i]
        s_theta = np.sqrt(max(0.0, 1.0 - c_theta * c_theta))
        for j in range(w_grid.shape[0]):
            w = w_grid[j]
            acc = np.zeros(3)
            for k in range(u.shape[0]):
                depth = w + u[k] * s_theta / dz  # source depth in layer units; the receiver's layers are 0 and 1
                lower = int(np.floor(depth))
                frac = 0.5 if half else depth - lower
                for a, alpha in ((lower, 1.0 - frac), (lower + 1, frac)):
                    if alpha == 0.0:
                        continue
                    for b, beta in ((0, 1.0 - w), (1, w)):
                        if beta == 0.0:
                            continue
                        e = abs(a - b) * dz
                        d = np.sqrt((u[k] * c_theta) ** 2 + e * e)
                        for c in range(3):
                            acc[c] += alpha * beta * du[k] * _interp(d, d_grid, lam, c)
            for c in range(3):
                out[i, j, c] = acc[c]


def plane_response(profile, dz, splat="linear", reach=None):
    """``C(cos_theta, w)`` per channel, shape (N_COS, N_W, 3), on ``cos_theta`` in [0, 1] and ``w`` in [0, 1].

    Returns ``(cos_grid, w_grid, C)``. With ``dz = 0`` (a single layer) the response is that of the flattened plane.

    Parameters
    ----------
    profile : Profile
    dz : float
        Layer spacing (mm), >= 0.
    splat : str
        ``linear`` or ``half``: how a sample's flux goes to its two layers.
    reach : float, optional
        Radius (mm) past which the profile is neglected (the line integrals reach 4 times as far); default: the
        radius holding all but 1e-5 of its energy, the largest over the channels.

    Returns
    -------
    cos_grid : numpy.ndarray, shape (N_COS,), float64
        ``cos_theta = |n . forward|`` from 0 (edge-on) to 1 (face-on).
    w_grid : numpy.ndarray, shape (N_W,), float64
        The receiver's depth fraction between its two layers, 0 to 1.
    C : numpy.ndarray, shape (N_COS, N_W, 3), float64
        The layers' response over the exact one (dimensionless); 1 in a channel whose total reflectance is 0.
    """
    reach = float(np.max(profile.radius_energy(1e-5))) if reach is None else reach
    d_grid, lam = line_integral_table(profile, 4.0 * reach)
    core = float(np.min(profile.radius_below(0.5)))
    t = np.linspace(-1.0, 1.0, 1601) * np.arcsinh(4.0 * reach / (1e-3 * core))
    u = 1e-3 * core * np.sinh(t)
    du = np.gradient(u)
    cos_grid = np.linspace(0.0, 1.0, N_COS)
    w_grid = np.linspace(0.0, 1.0, N_W)
    out = np.empty((N_COS, N_W, 3))
    _plane_response(cos_grid, w_grid, max(dz, 1e-12), splat == "half", u, du, d_grid, lam, out)
    total = np.broadcast_to(profile.total_reflectance, (3,))
    # A channel that reflects nothing (reduced albedo 0) has nothing to correct: C = 1.
    return cos_grid, w_grid, np.divide(out, total, out=np.ones_like(out), where=total > 0)


RESPONSES = KernelCache(size=8)


def cached_plane_response(profile, key, dz, splat):
    """:func:`plane_response`'s ``C`` table, cached per (profile ``key``, ``dz``, splat rule).

    Parameters
    ----------
    profile : Profile
    key : hashable
        Names the profile (:func:`~convsss.transport.kernels.profile_key` of its radial table).
    dz : float
        Layer spacing (mm).
    splat : str
        ``linear`` or ``half``.

    Returns
    -------
    numpy.ndarray, shape (N_COS, N_W, 3), float64
        ``C(cos_theta, w)`` per RGB channel, dimensionless.
    """
    entry = (key, float(dz), splat)
    response = RESPONSES.get(entry)
    if response is None:
        response = plane_response(profile, dz, splat)[2]
        RESPONSES.put(entry, response)
    return response


@njit(parallel=True, cache=True)
def apply_correction(exitance, cos_theta, w, irradiance, response, total):
    """The plane correction (Eq. P1, P2 of the module docstring) of ``exitance`` in place, ``C`` bilinear on its
    (cos, w) grid.

    Parameters
    ----------
    exitance : numpy.ndarray, shape (K, 3), float64
        The layers' exitance ``M_layers`` at K points (the irradiance's unit), corrected in place.
    cos_theta : numpy.ndarray, shape (K,), float64
        ``|n . forward|`` at each point (clamped to [0, 1]).
    w : numpy.ndarray, shape (K,), float64
        The point's depth fraction between its two layers (clamped to [0, 1]).
    irradiance : numpy.ndarray, shape (K, 3), float64
        ``E_q``, the local irradiance around each point.
    response : numpy.ndarray, shape (n_cos, n_w, 3), float64
        ``C`` on the uniform grids of :func:`plane_response` (n_cos, n_w >= 2).
    total : numpy.ndarray, shape (3,), float64
        ``R_total``, the profile's total diffuse reflectance per channel (dimensionless).

    Returns
    -------
    None
    """
    n_cos, n_w = response.shape[0], response.shape[1]
    for k in prange(exitance.shape[0]):
        x = min(max(cos_theta[k], 0.0), 1.0) * (n_cos - 1)
        y = min(max(w[k], 0.0), 1.0) * (n_w - 1)
        i = min(int(x), n_cos - 2)
        j = min(int(y), n_w - 2)
        fx = x - i
        fy = y - j
        for c in range(3):
            layers_over_exact = ((1 - fx) * ((1 - fy) * response[i, j, c] + fy * response[i, j + 1, c])
                                 + fx * ((1 - fy) * response[i + 1, j, c] + fy * response[i + 1, j + 1, c]))
            lit_plane = total[c] * irradiance[k, c]  # R_total E_q: the exact exitance of the lit tangent plane
            if layers_over_exact <= 1.0:
                exitance[k, c] += (1.0 - layers_over_exact) * lit_plane  # Eq. P1
            else:  # Eq. P2
                exitance[k, c] -= min((1.0 - 1.0 / layers_over_exact) * exitance[k, c],
                                      (layers_over_exact - 1.0) * lit_plane)
