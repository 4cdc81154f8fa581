"""Shadow rays of the surface estimators: what of a light's beam reaches a point, and which translucent object a
ray hit. One home for both (issue 59): the irradiance samples (paper Eq. 2, :mod:`.irradiance`) and the surface path
tracer's camera vertices (:mod:`.path_tracer`) step their shadow rays here, with one physics.

A shadow ray is blocked by an opaque surface or a dielectric boundary, and passes a surface whose BSDF lets light
through unchanged (a null boundary). Inside a translucent object's medium it keeps the light that crosses it
unscattered under the similarity relation,

    T = prod_chords e^{-sigma_t' l},                                                                       (Eq. S3)

``l`` each chord the ray cuts through an object of index-matched boundary and ``sigma_t' = sigma_a + (1 - g)
sigma_s`` the object's reduced extinction: its material's (:attr:`TranslucentObject.material`, what a fit tries),
and in a heterogeneous medium the medium's at the chord's midpoint (exact where only the albedo varies, as in a
constant volume or veins of albedo; the midpoint rule of the optical depth elsewhere). The reduced extinction is
what the transports' world is made of (the profiles, Eq. S2's single scattering, Eq. S3's crossings); the random
walk (:mod:`.walk`) simulates the medium itself, its own phase function and extinction, and steps its shadow rays
by ratio tracking with every channel's density kept (Eq. W1), so it has a stepper of its own.

A ray that has crossed more than :data:`MAX_CROSSINGS` surfaces counts as blocked, and one whose light is dimmed
below :data:`SHADOW_FLOOR` in every channel is done (0): light through 40 mm of milk is ``e^-40``, and stepping it
on through the rest of the mesh is what made the irradiance stage 20 times slower on such objects (issue 59).
"""

import drjit as dr

from ..backend import import_mitsuba
from .interiors import phase_g
from .traversal import hit_indices

mi = import_mitsuba()

#: The most surfaces a shadow ray crosses (index-matched boundaries of translucent objects) before it counts as
#: blocked.
MAX_CROSSINGS = 16
#: A shadow ray whose transmittance falls below this in every channel is done: its light counts as 0.
SHADOW_FLOOR = 1e-7


def classify(objects, si):
    """Per lane of ``si``: the index of the translucent object of ``objects`` hit (mi.Int32, -1: none) and its eta
    (mi.Float, 1 where none).

    An object is the pair (instance, shape): an instanced shape is shared by every instance of its shapegroup, and
    ``si.instance`` is null (index 0) on a plain shape.
    """
    shapes, instances = hit_indices(mi, si)
    valid = si.is_valid()
    which = dr.full(mi.Int32, -1, dr.width(si.p))
    eta = dr.full(mi.Float, 1.0, dr.width(si.p))
    for k, obj in enumerate(objects):
        on_object = valid & obj.hit(shapes, instances)
        which = dr.select(on_object, k, which)
        eta = dr.select(on_object, obj.eta, eta)
    return which, eta


class Shadows:
    """The shadow rays of one scene's translucent ``objects`` (module doc), ``unit_mm`` mm per scene unit."""

    def __init__(self, scene, objects, unit_mm):
        self.scene, self.objects = scene, objects
        #: Whether any object lets a shadow ray through (else one ``ray_test`` answers).
        self.any_passes = any(obj.boundary == "null" for obj in objects)
        #: Per object: its constant ``sigma_t'`` per scene unit (Color3f), or ``(medium, g)`` for a heterogeneous
        #: one, whose extinction is read at each chord's midpoint.
        self.extinction = [mi.Color3f(*(obj.material.sigma_t_prime * unit_mm).tolist()) if obj.classes is None
                           else (obj.shape.interior_medium(), phase_g(mi.traverse(obj.shape.interior_medium())))
                           for obj in objects]

    def visibility(self, it, ds, active):
        """What of the light of emitter sample ``ds`` reaches the interaction ``it`` (Color3f, module doc)."""
        if not self.any_passes:
            return dr.select(active & ~self.scene.ray_test(it.spawn_ray_to(ds.p), active), mi.Color3f(1.0), 0.0)
        return self.transmittance(it.spawn_ray_to(ds.p), active)

    def _chord_extinction(self, which, ray, t, active):
        """Per lane, ``sigma_t'`` (per scene unit) along the chord ``ray(0)`` to ``ray(t)`` through object
        ``which`` (module doc; 0 where none)."""
        out = dr.zeros(mi.Color3f, dr.width(which))
        for k, extinction in enumerate(self.extinction):
            if isinstance(extinction, tuple):
                medium, g = extinction
                here = active & (which == k)
                mei = dr.zeros(mi.MediumInteraction3f, dr.width(which))
                mei.p = ray(0.5 * t)
                sigma_s, _, sigma_t = medium.get_scattering_coefficients(mei, here)
                out = dr.select(here, sigma_t - g * sigma_s, out)
            else:
                out = dr.select(which == k, extinction, out)
        return out

    @dr.syntax
    def transmittance(self, ray, active):
        """What of a beam along ``ray`` (towards a light, ``maxt`` its distance) arrives (Color3f, module doc): the
        ray stepped from surface to surface in one symbolic loop."""
        scene = self.scene
        active = mi.Bool(active)
        transmittance = dr.select(active, mi.Color3f(1.0), mi.Color3f(0.0))
        ray = mi.Ray3f(ray)
        inside = dr.full(mi.Int32, -1, dr.width(transmittance))
        crossings = mi.UInt32(0)
        while active:
            si = scene.ray_intersect(ray, active)
            hit = active & si.is_valid()
            chord = dr.select(hit, si.t, ray.maxt)
            dimmed = active & (inside >= 0)
            transmittance[dimmed] *= dr.exp(-self._chord_extinction(inside, ray, chord, dimmed) * chord)
            which, _ = classify(self.objects, si)
            through = hit & (dr.max(si.bsdf(ray).eval_null_transmission(si, hit)) > 0.0)
            transmittance[hit & ~through] = 0.0
            inside[through & (which >= 0)] = dr.select(inside == which, -1, which)
            crossings += 1
            active = through & (crossings < MAX_CROSSINGS) & (dr.max(transmittance) >= SHADOW_FLOOR)
            transmittance[through & ~active] = 0.0
            remaining = ray.maxt - si.t
            ray[active] = si.spawn_ray(ray.d)
            ray.maxt[active] = remaining
            active &= remaining > 0
        return transmittance
