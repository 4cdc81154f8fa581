"""The forward model of a fit (:mod:`convsss.fitting`): the render of ``scene`` with one translucent object's material
set to the one tried, by the random walk or by the transport, as the default render would have it; and the scene's
values it changes (the boundary's index, the walk's medium) read and given back. What each evaluation reuses, and
why the paths are drawn as they are: :mod:`convsss.fitting`'s docstring.
"""

import dataclasses
import time

import numpy as np

from .errors import ConvsssError


class Forward:
    """The render of ``scene`` through ``sensor`` with object ``index``'s material set, (H, W, 3) float64.

    ``integrator`` is a ``convsss`` integrator; ``seed`` and ``spp`` fixed for every evaluation; ``walks``: its
    renders are random walks (each drawn by its own material, or one it is given), else the transport's. See
    :mod:`convsss.fitting`'s docstring for what each evaluation reuses; ``evaluations`` and ``seconds`` count them."""

    def __init__(self, scene, integrator, sensor, index, seed=0, spp=4, walks=False):
        self.scene, self.integrator, self.sensor, self.index = scene, integrator, sensor, index
        self.seed, self.spp, self.walks = seed, spp, walks
        self.evaluations, self.seconds = 0, 0.0
        #: The index the boundary's BSDF has now (None: the scene's).
        self._eta = None
        #: The material the next evaluation sizes the samples by and draws the paths with (:meth:`replan`).
        self._replan = None

    def replan(self, material):
        """From the next evaluation on, the samples are sized by ``material``'s profile (the scene's sized them) and
        the paths' choices drawn with its sigma_t' (``TranslucentObject.sampling``)."""
        self._replan = material

    @property
    def obj(self):
        return self.integrator.prepared.objects[self.index]

    def __call__(self, material, drawn=None):
        """The render of ``material``; with walks, their paths drawn by ``drawn`` (default: ``material`` itself), so
        that renders of materials near ``drawn`` differ smoothly (the Jacobian's)."""
        start = time.perf_counter()
        if material.eta != (self._eta or self.obj.eta):
            set_boundary_eta(self.obj.shape, material.eta)
            self._eta = material.eta
        if self.walks:
            image = self._walked(material, drawn or material)
        else:
            image = self._transported(material)
        self.evaluations += 1
        self.seconds += time.perf_counter() - start
        return image

    def _walked(self, material, drawn):
        """The random walk's render of ``material``, its paths drawn by the object's medium set to ``drawn`` (as near
        as the medium holds it: a grey one takes the channels' mean) and weighed by ``material``."""
        self._weigh(material, drawn)
        return np.array(self.integrator.render_prepared(spp=self.spp, seed=self.seed), dtype=np.float64)[..., :3]

    def _weigh(self, material, drawn):
        """The object's medium set to ``drawn`` (:meth:`_walked`), its walks weighed by ``material``; returns the
        medium's phase function's mean cosine."""
        import mitsuba as mi

        from .media.dicts import medium_parameters
        from .pipeline.interiors import phase_g

        medium = self.obj.shape.interior_medium()
        params = mi.traverse(medium)
        g, unit_mm = phase_g(params), self.integrator.params.unit_mm
        _set_medium(params, medium_parameters(unreduced(drawn, g), unit_mm))
        weighed = unreduced(material, g)
        sigma_t, sigma_s = (mi.Color3f(*(c * unit_mm).tolist()) for c in (weighed.sigma_t_prime, weighed.sigma_s_prime))
        self.integrator.walk.weigh(medium, sigma_t, sigma_s)
        return g

    def derivatives(self, material):
        """Where the render walks: its image of ``material`` and the image's derivatives with respect to the reduced
        albedo and the log of the reduced mean free path (mm) per channel, three (H, W, 3) arrays from one walk of the
        same samples (:func:`~convsss.pipeline.derivatives.derivative_images`: no finite-difference renders)."""
        from .pipeline.derivatives import derivative_images

        start = time.perf_counter()
        g = self._weigh(material, material)
        image, d_sigma_t, d_sigma_s = derivative_images(self.integrator, self.obj.shape.interior_medium(), self.spp,
                                                        self.seed)
        unit_mm = self.integrator.params.unit_mm
        mfp = 1.0 / material.sigma_t_prime
        sigma = unreduced(material, g)
        # sigma_s = alpha' / (mfp (1 - g)), sigma_a = (1 - alpha') / mfp, sigma_t = sigma_s + sigma_a (per mm)
        ds_dalbedo = 1.0 / (mfp * (1.0 - g))
        dt_dalbedo = ds_dalbedo - 1.0 / mfp
        d_albedo = (d_sigma_t * dt_dalbedo + d_sigma_s * ds_dalbedo) * unit_mm
        d_log_mfp = -(d_sigma_t * sigma.sigma_t_prime + d_sigma_s * sigma.sigma_s_prime) * unit_mm
        self.evaluations += 1
        self.seconds += time.perf_counter() - start
        return image, d_albedo, d_log_mfp

    def _transported(self, material):
        """The transport's render of ``material`` (the reuse of :mod:`convsss.fitting`'s docstring)."""
        from .profiles.models import is_model, parse_profile_spec, resolve_profile

        p = self.integrator.params
        default, per_object = parse_profile_spec(p.profile)
        spec = per_object.get(self.obj.name, per_object.get(self.obj.name.split("/")[0], default))
        if not is_model(spec):
            raise ConvsssError(f"translucent shape {self.obj.name!r} renders with the tabulated profile {spec!r}: "
                               "a fit needs a profile model (the integrator's profile parameter)")
        # The paths' choices drawn with one material for every evaluation (the scene's, until replan), so that
        # they do not move with the material tried.
        sampling = self._replan or self.obj.sampling or self.obj.material
        objects = list(self.integrator.prepared.objects)
        trial = self.obj.with_material(material, resolve_profile(spec, material, p.profile_total, p.orders))
        objects[self.index] = dataclasses.replace(trial, sampling=sampling)
        # The same samples, their irradiance drawn again: it depends on the reduced albedo (the entry gain) and on
        # sigma_t' too, through the indirect paths that cross the object's thin parts (Eq. S3), so retransport,
        # which keeps it, would leave the image a little off the material.
        self.integrator.reprepare(objects, replan=self._replan is not None)
        self._replan = None
        return np.array(self.integrator.render_prepared(spp=self.spp, seed=self.seed), dtype=np.float64)[..., :3]


def unreduced(material, g):
    """``material``'s coefficients under a phase function of mean cosine ``g``, as the :class:`~convsss.materials.
    Material` of an isotropic one (``sigma_s = sigma_s' / (1 - g)``, the similarity relation; ``sigma_a`` as it is):
    what a Mitsuba medium of that phase function holds."""
    from .materials import Material

    return Material(material.sigma_s_prime / (1.0 - g), material.sigma_a, material.eta, material.name)


def _set_medium(params, coefficients):
    """Give a Mitsuba homogeneous medium (its traversed ``params``) the ``coefficients`` of
    :func:`~convsss.media.dicts.medium_parameters`; a grey coefficient (one value) the channels' mean."""
    import mitsuba as mi

    params["scale"] = coefficients["scale"]
    for name in ("sigma_t", "albedo"):
        value = coefficients[name]
        key = f"{name}.value.value" if f"{name}.value.value" in params else f"{name}.value"
        held = params[key]
        params[key] = type(held)(*value.tolist()) if isinstance(held, mi.Color3f) else type(held)(float(np.mean(value)))
    params.update()


def medium_values(medium):
    """A copy of a Mitsuba medium's traversed values (:func:`restore_medium` gives them back)."""
    import mitsuba as mi

    params = mi.traverse(medium)
    return {key: type(params[key])(params[key]) for key in params.keys()}


def restore_medium(medium, values):
    """Give a Mitsuba medium back the ``values`` of :func:`medium_values`."""
    import mitsuba as mi

    params = mi.traverse(medium)
    for key, value in values.items():
        params[key] = value
    params.update()


def set_boundary_eta(shape, eta):
    """Give ``shape``'s boundary BSDF (a dielectric or rough dielectric) the relative index ``eta``."""
    import mitsuba as mi

    params = mi.traverse(shape)
    params["bsdf.eta"] = eta
    params.update()
