"""Oblique incidence: how much more light a semi-infinite medium sends back when it enters at a slant.

Every profile model here is the response to a beam entering along the normal. Light that enters at a slant has its
first collisions closer to the surface and escapes more: for a reduced albedo of 0.7 (skin's blue), a beam at 60°
inside the medium comes back 25 % more than a normal one, and a cosine-weighted (diffuse) illumination 24 % more on
average; at whole milk's 0.9996 the effect is 1 %. The profile models keep their shape, and the flux each incoming
direction deposits is multiplied by the medium's own ratio

    g(mu) = rho(mu) / rho(1),                                                                             (Eq. O1)

``rho(mu)`` the total flux that leaves a semi-infinite, isotropically scattering half-space (the reduced medium)
per unit flux transmitted into it along a direction at cosine ``mu`` to the inward normal. It is computed exactly
(radiative transfer, not diffusion), per ``(alpha', eta)``:

- Index-matched boundary (Chandrasekhar 1960, *Radiative Transfer*, §47): a collimated beam of unit flux per unit
  area at ``mu_0`` is reflected as the radiance

      I(mu) = alpha'/(4 pi) H(mu) H(mu_0) / (mu + mu_0),                                                  (Eq. O2)

  with Chandrasekhar's ``H``-function of the albedo, the root of
  ``1/H(mu) = sqrt(1 - alpha') + alpha'/2 ∫_0^1 mu' H(mu') / (mu + mu') dmu'``; its flux is the plane albedo
  ``1 - H(mu_0) sqrt(1 - alpha')``.
- A smooth dielectric boundary (``eta != 1``) reflects the upward radiance back in with ``F_r(1/eta, mu)`` (1 past
  the critical angle). The medium reflects that downward radiance ``d`` again by Eq. O2, as
  ``(alpha'/2) H(mu) ∫ H(mu') mu' d(mu') / (mu + mu') dmu'``; so the upward radiance under the boundary solves
  ``u = I + K (F_r u)`` (the adding method: every round trip, summed), and
  ``rho(mu_0) = 2 pi ∫ (1 - F_r(1/eta, mu)) u(mu) mu dmu``.                                              (Eq. O3)

By reciprocity the same gain weights the light that **leaves** (the BSSRDF is symmetric in its two directions): the
only separable, reciprocal split of the half-space's reflection that keeps ``rho(mu_0)`` for every entering direction
is ``f(mu_0, mu) ∝ F_t(mu_0) g(mu_0) F_t(mu) g(mu)``, so paper Eq. 7 becomes

    L_o = F_t(eta, w_o) g(mu_o) M / (pi k),   k = (2 / T_d) ∫_0^1 F_t(eta, mu) g(mu_in(mu)) mu dmu,          (Eq. O4)

``k`` keeping the exitance ``T_d M`` that Eq. 7 sends out. At low albedo light leaves mostly towards grazing (Eq.
O2's ``1/(mu + mu_0)``), where the Lambertian Eq. 7 is up to 30 % too dark on a sphere; Eq. O4 is within 1 % of Eq. O2
there, for any albedo (docs/history/benchmarks-notebook.md, "Oblique incidence").

**Single scattering on its own** (the renderer's ``single_scattering = traced``: the shader traces it through the
object's real shape, :mod:`convsss.pipeline.path_tracer`). Of Eq. O2's radiance, the light scattered once and leaving
without an internal reflection is ``alpha'/(4 pi) / (mu + mu_0)`` (``H = 1``); its flux is

    rho_1(mu_0) = 2 pi ∫ (1 - F_r(1/eta, mu)) alpha'/(4 pi) mu / (mu + mu_0) dmu,                         (Eq. S1)

``(alpha'/2) (1 - mu_0 ln(1 + 1/mu_0))`` when index-matched; ``Orders.MULTIPLE`` gives ``rho - rho_1``, what the
profile then carries, with its gains (Eq. O1, O4) taken from that part alone.

Both are azimuth-independent for isotropic scattering, so a Gauss–Legendre rule in ``mu`` solves them to
machine precision. ``rho(1) / T_d(eta)`` is the slab's total reflectance that ``convsss profile validate`` measures
by Monte Carlo (:mod:`convsss.profiles.slab`, which also takes an oblique beam: the tests compare both).
"""

from enum import Enum
from functools import lru_cache

import numpy as np

from ..errors import ConvsssError
from ..fresnel import check_eta, diffuse_transmittance, fresnel_reflectance

#: Gauss–Legendre nodes on (0, 1) for the H-function and the adding method.
NODES = 96
#: Nodes of the gain tables (uniform in the cosine inside the medium, 0 to 1).
GAIN_NODES = 65
class Orders(str, Enum):
    """What of the escaping light a profile and its gains carry: ``all`` of it, or the ``multiple`` scattering (all
    but the single scattering of Eq. S1, which the path tracer traces). Equal to its name as a string."""

    ALL = "all"
    MULTIPLE = "multiple"

    def __str__(self):
        return self.value


#: The names :class:`Orders` takes.
ORDERS = tuple(o.value for o in Orders)


def _rule(eta=1.0):
    """Nodes and weights on (0, 1): Gauss–Legendre, split at the critical cosine ``sqrt(1 - 1/eta^2)`` where
    ``F_r`` has a kink, and past it in ``s^2`` to absorb the square root of ``F_r`` there."""
    x, w = np.polynomial.legendre.leggauss(NODES // 2)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    if eta <= 1.0:
        return np.concatenate([0.5 * x, 0.5 + 0.5 * x]), np.concatenate([0.5 * w, 0.5 * w])
    critical = np.sqrt(1.0 - 1.0 / eta**2)
    return (np.concatenate([critical * x, critical + (1.0 - critical) * x * x]),
            np.concatenate([critical * w, 2.0 * (1.0 - critical) * x * w]))


@lru_cache(maxsize=256)
def _h_nodes(albedo, eta=1.0):
    """``H`` at the nodes of ``_rule(eta)``: the root of ``H_i (sqrt(1 - albedo) + albedo/2 sum_j K_ij H_j) = 1``,
    ``K_ij = w_j mu_j / (mu_i + mu_j)`` (the ``1/H`` form of Eq. O2's H-equation), by Newton's method from ``H = 1``
    (a few steps at any albedo < 1, where the fixed-point iteration takes up to 1e5 near albedo 1)."""
    mu, w = _rule(eta)
    root = np.sqrt(max(1.0 - albedo, 0.0))
    kernel = w * mu / (mu[:, None] + mu)
    h = np.ones(NODES)
    for _ in range(100):
        s = root + 0.5 * albedo * kernel @ h
        residual = h * s - 1.0
        if np.max(np.abs(residual)) < 1e-14:
            break
        h = h - np.linalg.solve(np.diag(s) + 0.5 * albedo * h[:, None] * kernel, residual)
    return h


def h_function(albedo, mu):
    """Chandrasekhar's ``H(mu)`` for isotropic scattering of single-scattering albedo ``albedo`` (Eq. O2)."""
    albedo = _check_albedo(albedo)
    nodes, w = _rule()
    h = _h_nodes(albedo)
    return _h_at(albedo, nodes, w, h, mu)


def _h_at(albedo, nodes, w, h, mu):
    """``H(mu)`` from its values ``h`` at the quadrature ``nodes``, ``w`` (the right side of its equation)."""
    mu = np.asarray(mu, dtype=np.float64)
    integral = np.sum(w * nodes * h / (mu[..., None] + nodes), axis=-1)
    return 1.0 / (np.sqrt(max(1.0 - albedo, 0.0)) + 0.5 * albedo * integral)


def _check_albedo(albedo):
    albedo = float(albedo)
    if not 0.0 <= albedo <= 1.0:
        raise ConvsssError(f"albedo={albedo!r} is not allowed: it must lie in [0, 1]")
    return min(albedo, 1.0 - 1e-7)  # alpha' = 1 as its limit (g is within 5e-4 of 1; the iteration needs absorption)


def escaped(albedo, eta, mu, orders=Orders.ALL):
    """``rho(mu)`` of Eq. O3: the flux that leaves the half-space per unit flux transmitted into it at cosine ``mu``
    (inside the medium, to the inward normal; array-like in (0, 1]). Reduced albedo ``albedo``, relative index
    ``eta`` of a smooth boundary (1: index-matched); ``orders`` multiple: without the single scattering of Eq. S1."""
    albedo, eta = _check_albedo(albedo), check_eta(eta)
    if orders not in ORDERS:
        raise ConvsssError(f"orders={orders!r} is not allowed: choose from {', '.join(ORDERS)}")
    mu0 = np.clip(np.asarray(mu, dtype=np.float64), 1e-6, 1.0)
    if albedo == 0.0:
        return np.zeros(mu0.shape)
    nodes, w = _rule(eta)
    h = _h_nodes(albedo, eta)
    h0 = _h_at(albedo, nodes, w, h, mu0)
    first = albedo / (4.0 * np.pi) * h * h0[..., None] / (nodes + mu0[..., None])  # Eq. O2, (..., NODES)
    back = fresnel_reflectance(1.0 / eta, nodes)
    kernel = 0.5 * albedo * h[:, None] * h * w * nodes / (nodes[:, None] + nodes) * back
    u = np.linalg.solve(np.eye(NODES) - kernel, first.reshape(-1, NODES).T).T.reshape(first.shape)
    if orders == Orders.MULTIPLE:
        u = u - albedo / (4.0 * np.pi) / (nodes + mu0[..., None])  # less Eq. S1's once-scattered radiance
    return 2.0 * np.pi * np.sum(w * nodes * (1.0 - back) * u, axis=-1)  # Eq. O3


@lru_cache(maxsize=512)
def gain_table(albedo, eta, orders=Orders.ALL, carried=None):
    """Eq. O1 at :data:`GAIN_NODES` cosines ``0, ..., 1`` inside the medium (1 where nothing scatters), read back
    linearly by :func:`gain`: the flux of the light of ``orders`` (:data:`ORDERS`) over the normal beam's flux of the
    light the profile carries, ``carried`` (default: ``orders``); ``orders`` all, ``carried`` multiple is light whose
    single scattering the profile spreads as its own (``rho(mu) / (rho - rho_1)(1)``)."""
    mu = np.linspace(0.0, 1.0, GAIN_NODES)
    rho = escaped(albedo, eta, mu, orders)
    normal = rho[-1] if carried in (None, orders) else float(escaped(albedo, eta, 1.0, carried))
    if normal <= 0.0:
        return np.ones(GAIN_NODES)
    return rho / normal


def transmitted_cosine(eta, cos_outside):
    """The cosine inside the medium of a direction refracted in from ``cos_outside`` (Snell's law)."""
    cos_outside = np.clip(np.abs(np.asarray(cos_outside, dtype=np.float64)), 0.0, 1.0)
    return np.sqrt(np.maximum(1.0 - (1.0 - cos_outside**2) / check_eta(eta) ** 2, 0.0))


def gain(albedo, eta, cos_outside, orders=Orders.ALL):
    """Per channel, Eq. O1 for light arriving from outside at ``cos_outside``: (..., 3) for ``albedo`` of shape (3,)."""
    mu = transmitted_cosine(eta, cos_outside)
    nodes = np.linspace(0.0, 1.0, GAIN_NODES)
    return np.stack([np.interp(mu, nodes, gain_table(float(a), float(eta), orders)) for a in np.asarray(albedo)],
                    axis=-1)


#: Outside cosines of the trapezoid rule of :func:`exit_normalization`.
EXIT_NODES = 4097


def exit_normalization(albedo, eta, orders=Orders.ALL):
    """``k`` of Eq. O4 per channel, (3,) for ``albedo`` of shape (3,): ``(2 / T_d) ∫ F_t(eta, mu) g mu dmu`` over
    the outside cosine ``mu`` (the gain read as :func:`gain` reads it), so that ``F_t g / (pi k)`` sends out ``T_d``
    of ``M`` as paper Eq. 7 does."""
    mu = np.linspace(0.0, 1.0, EXIT_NODES)
    weight = (1.0 - fresnel_reflectance(check_eta(eta), mu))[:, None] * gain(albedo, eta, mu, orders) * mu[:, None]
    return 2.0 * np.trapezoid(weight, mu, axis=0) / diffuse_transmittance(eta)
