"""Fresnel terms at the smooth boundary of a translucent object.

``eta`` is always the relative index ``n_object / n_outside`` (the paper's ``n_ob / n_med``), and ``cos_theta`` the
cosine between the direction and the normal on the *outside* of the object. By reciprocity the transmittance of a
ray leaving the object towards ``w_o`` equals that of a ray arriving from ``w_o``, so one function serves both
``F_t(eta, w_i)`` of paper Eq. 2 and ``F_t(eta, w_o)`` of Eq. 1 and 7.
"""

from functools import cache

import numpy as np

from .errors import ConvsssError


def check_eta(eta):
    """Return ``eta`` as a float after checking that it is a finite positive number."""
    value = float(eta)
    if not np.isfinite(value) or value <= 0.0:
        raise ConvsssError(f"relative index of refraction eta={eta!r} is not allowed: it must be a finite number > 0")
    return value


def same_eta(a, b):
    """Whether two relative indices are the same at the float32 precision Mitsuba stores a BSDF's ``eta`` in (a
    preset's 1.4 and the scene's 1.39999998 are one index)."""
    return bool(np.float32(a) == np.float32(b))


def fresnel_reflectance(eta, cos_theta):
    """Unpolarized Fresnel reflectance of a smooth dielectric boundary.

    ``F_r = (r_s^2 + r_p^2) / 2`` with ``r_s = (cos_i - eta cos_t)/(cos_i + eta cos_t)``,
    ``r_p = (eta cos_i - cos_t)/(eta cos_i + cos_t)`` and Snell's law ``sin_t = sin_i / eta``.
    Total internal reflection (possible when ``eta < 1``) gives 1; ``eta = 1`` gives 0.

    Parameters
    ----------
    eta : float
        Relative index ``n_object / n_outside`` (> 0).
    cos_theta : array_like, any shape
        Cosine of the angle to the normal on the outside; its sign is ignored (values are clipped to [0, 1]).

    Returns
    -------
    numpy.ndarray, float64
        Reflectance in [0, 1] (dimensionless), the shape of ``cos_theta``.
    """
    eta = check_eta(eta)
    cos_i = np.clip(np.abs(np.asarray(cos_theta, dtype=np.float64)), 0.0, 1.0)
    if eta == 1.0:  # index-matched: no boundary, no reflection (also at grazing incidence, where the formula is 0/0)
        return np.zeros_like(cos_i)
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    tir = sin2_t >= 1.0
    cos_t = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        r_s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
        r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
        reflectance = 0.5 * (r_s * r_s + r_p * r_p)
    reflectance = np.where(tir | ~np.isfinite(reflectance), 1.0, reflectance)
    return np.clip(reflectance, 0.0, 1.0)


def fresnel_transmittance(eta, cos_theta):
    """``F_t(eta, cos) = 1 - F_r(eta, cos)``: the transmittance in paper Eq. 1, 2 and 7.

    Parameters
    ----------
    eta : float
        Relative index ``n_object / n_outside`` (> 0).
    cos_theta : array_like, any shape
        Cosine of the angle to the normal on the outside; its sign is ignored.

    Returns
    -------
    numpy.ndarray, float64
        Transmittance in [0, 1] (dimensionless), the shape of ``cos_theta``.

    Examples
    --------
    >>> fresnel_transmittance(1.5, [1.0, 0.0])
    array([0.96, 0.  ])
    """
    return 1.0 - fresnel_reflectance(eta, cos_theta)


def diffuse_fresnel_reflectance(eta):
    """Average diffuse Fresnel reflectance ``F_dr`` by the Egan–Hilgeman fit (Jensen et al. 2001, Eq. after 4).

    ``F_dr = -1.4399/eta^2 + 0.7099/eta + 0.6681 + 0.0636 eta``. Exactly 0 at ``eta = 1`` is not what the fit gives
    (it gives 0.0017); the fit is used as published so numbers match the literature.
    """
    eta = check_eta(eta)
    return -1.4399 / eta**2 + 0.7099 / eta + 0.6681 + 0.0636 * eta


@cache
def _gauss_legendre(n):
    return np.polynomial.legendre.leggauss(n)


@cache
def fresnel_moment(eta, n, pieces=16, nodes=48):
    """``C_n = ∫_0^1 F_r(eta, mu) mu^n dmu``: the n-th angular moment of the Fresnel reflectance (d'Eon 2012, "A
    better dipole"; pbrt's ``FresnelMoment`` fits), by composite Gauss–Legendre quadrature, exact below the critical
    angle when ``eta < 1`` (total internal reflection) and in a variable that smooths the kink there.

    For light *inside* an object of relative index ``eta``, the boundary is seen with the relative index ``1/eta``.

    Parameters
    ----------
    eta : float
        Relative index of the far side over the near side (> 0).
    n : int
        The moment (0, 1, 2, ...).

    Returns
    -------
    float
    """
    eta = check_eta(eta)
    x, w = _gauss_legendre(nodes)
    # Below the critical cosine mu_c (eta < 1) F_r = 1; above it F_r has a square-root kink at mu_c, smoothed by
    # mu = mu_c + (1 - mu_c) v^2 (for eta >= 1, mu_c = 0 and the map is harmless).
    mu_c = float(np.sqrt(1.0 - eta * eta)) if eta < 1.0 else 0.0
    total = mu_c ** (n + 1) / (n + 1)
    edges = np.linspace(0.0, 1.0, pieces + 1)
    for a, b in zip(edges[:-1], edges[1:]):
        v = 0.5 * (b - a) * x + 0.5 * (a + b)
        mu = mu_c + (1.0 - mu_c) * v * v
        jacobian = 2.0 * (1.0 - mu_c) * v
        total += 0.5 * (b - a) * float(np.sum(w * fresnel_reflectance(eta, mu) * mu**n * jacobian))
    return total


def diffuse_transmittance(eta):
    """``T_d = (1/pi) ∫ F_t(eta, w) cos dw = 1 - 2 C_1(eta)`` over the outer hemisphere: the fraction of a uniform
    radiance outside that enters the object (through Eq. 2), and, by reciprocity, the fraction of ``M`` that Eq. 7's
    ``(1/pi) F_t(eta, w_o) M`` carries out of it."""
    return 1.0 - 2.0 * fresnel_moment(float(eta), 1)
