"""Media whose coefficients vary in space: a Mitsuba ``heterogeneous`` interior as a few homogeneous classes.

A translucent object's interior may be a ``heterogeneous`` medium whose ``sigma_t`` and ``albedo`` are volume
textures (``gridvolume``, ``constvolume``), as Mitsuba writes it, so that the same file renders with ``volpathmis``.
Mitsuba evaluates the coefficients (``Medium.get_scattering_coefficients``) wherever convsss asks.

* **The medium under a surface point** (:meth:`MediumField.explored_coefficients`). Light entering at a point diffuses
  through the medium under it, a few diffusion lengths ``l`` down and across; what it meets there (a dark vein
  below or beside a light surface, a dense core under a thin skin) absorbs it as much as what lies at the surface.
  To first order, a change of the coefficients at a point ``y`` changes the exitance at ``x`` by the product of the
  diffuse fluence coming from the entry and of its adjoint going to the exit; both are the half-space's Green's
  function, about ``cos(theta) exp(-rho/l) / rho^2`` at the distance ``rho`` and the angle ``theta`` to the inward
  normal ``n``, so per unit of ``rho`` and of solid angle the weight is ``cos^2(theta) exp(-2 rho/l)``, and a surface
  point stands for

      sigma(x) = int_{w.n < 0} int_0^{2l} sigma(x + rho w) exp(-2 rho/l) cos^2 theta drho dw / (same of 1)  (Eq. H2)

  per channel, ``l = 1/sqrt(3 sigma_a sigma_t')`` from this mean itself (two rounds, the first from the surface's
  values), sampled at :data:`DEPTHS` points per surface point (a rank-1 lattice in distance, ``cos^3 theta`` and
  azimuth, shifted per point) and counting only the medium's box. For a homogeneous medium it is the medium's
  coefficients.
* **The classes** (:func:`medium_classes`): over points spread on the surface, the explored coefficients present. Per
  channel they are points ``q = (1/2 log(1 - alpha'), log l)`` (the log of the diffusion length over the mean free
  path, and of the mean free path ``l``), which lie near one line when one thing varies (two media mixed, a colour
  map at one mean free path, one medium fading into another); the line is their principal axis. Nodes spaced
  :data:`CLASS_STEP` along it, at most :data:`MAX_CLASSES`, are the classes: node ``k`` of every channel makes the
  homogeneous :class:`~convsss.materials.Material` of class ``k``, whose profile is a model's as for any object.
* **The samples** (:meth:`MediumClasses.weights`): each sample's explored coefficients, projected on its channel's
  axis, split between the two nearest nodes (hat weights, summing to 1 per channel). The projections are tabulated
  once per object on points spread over its surface at a quarter of the classes' shortest diffusion length
  (:data:`TABLE_SPACING`; Eq. H2 averages over about half a diffusion length, so they vary no faster) and read at
  any surface point from its :data:`TABLE_NEIGHBOURS` nearest entries, inverse-distance weighted: the cost of a
  render's weights is set by the object's size in diffusion lengths, not by its samples, and every pass reads the
  same table. Light entering at a sample
  spreads with its classes' profiles, and light leaving at a point with the point's (:mod:`convsss.transport.mixture`,
  Eq. H1).

A medium whose coefficients are the same wherever the survey looked is homogeneous: it renders exactly as the
``homogeneous`` medium of those values. What varies off the axis (two independent maps, say albedo and mean free
path, in one channel) is read at its projection on it. Eq. H2 reads the medium's volumes, not the object: near a
thin part or an edge, points beyond the object's surface (but within the volumes' box) count as if they were
inside (the object's own shape is not traced there), and the profile stays a half-space's.
"""

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConvsssError
from ..materials import CHANNELS, Material

#: Surface points of the survey, and lattice points per side of the object's box checked for bad coefficients.
SURVEY_POINTS = 4096
LATTICE = 24
#: Spacing of the class nodes along a channel's axis (natural-log units: 0.4 is a 49 % step of the diffusion length
#: or of the mean free path; a finer step barely changes a veined marble's render, a coarser one changes it more), and
#: their largest count (each class builds its transports).
CLASS_STEP = 0.4
MAX_CLASSES = 8
#: ``1 - alpha'`` at least this (a channel without absorption has an infinite diffusion length).
ABSORPTION_FLOOR = 1e-6
#: Lookups per surface point in Eq. H2, its reach in diffusion lengths, and its longest in mm (a channel without
#: absorption has an unbounded diffusion length).
DEPTHS = 16
COLUMN = 2.0
COLUMN_CAP_MM = 1e3
#: Surface points per round of :meth:`MediumField.explored_coefficients` (``DEPTHS`` Mitsuba lookups each).
CHUNK = 1 << 15
#: The table of :meth:`MediumClasses.weights`: its spacing as a fraction of the classes' shortest diffusion length,
#: its fewest and most points (a coarser spacing beyond), and the entries read per point.
TABLE_SPACING = 0.25
TABLE_POINTS = (SURVEY_POINTS, 1 << 18)
TABLE_NEIGHBOURS = 4
#: Coefficients within this relative spread over the survey are one medium's (a constant volume's values read back
#: through float32 interpolation differ in their last bits).
CONSTANT_SPREAD = 1e-5


@dataclass(frozen=True, eq=False)
class MediumField:
    """The reduced coefficients of a Mitsuba medium at any point: ``medium`` (Mitsuba's), ``unit_mm`` mm per scene
    unit, ``g`` the phase function's mean cosine, ``name`` the shape's (for errors)."""

    medium: object
    unit_mm: float
    g: float
    name: str

    def _scene_coefficients(self, points_mm):
        """Mitsuba's ``(sigma_s, sigma_t)``, (N, 3) each per scene unit, at ``points_mm`` (N, 3) mm."""
        import drjit as dr
        import mitsuba as mi

        points = (np.asarray(points_mm, dtype=np.float64) / self.unit_mm).T.astype(np.float32)
        mei = dr.zeros(mi.MediumInteraction3f, points.shape[1])
        mei.p = mi.Point3f(*points)
        mei.medium = mi.MediumPtr(self.medium)
        sigma_s, _, sigma_t = self.medium.get_scattering_coefficients(mei, True)
        # A constant volume's value comes back once, not per point: broadcast to every point.
        return tuple(np.broadcast_to(np.asarray(a, dtype=np.float64).reshape(3, -1).T, (points.shape[1], 3))
                     for a in (sigma_s, sigma_t))

    def _stored(self, name):
        """The (3,) value of volume ``name`` (``albedo``, ``sigma_t``) where Mitsuba exposes it and it is the same
        everywhere (a ``constvolume``, a ``gridvolume`` of equal cells), else None."""
        import mitsuba as mi

        params = mi.traverse(self.medium)
        for key in (f"{name}.value.value", f"{name}.data"):
            if key in params:
                values = np.asarray(params[key], dtype=np.float64)
                values = values.reshape(-1, values.shape[-1] if key.endswith(".data") else values.size)
                if np.all(values == values[0]):
                    return np.broadcast_to(values[0], (3,)) if values.shape[1] in (1, 3) else None
        return None

    def constant(self, points_mm, eta):
        """The one :class:`Material` (boundary index ``eta``) of the coefficients at ``points_mm`` (N, 3) where
        they spread by at most :data:`CONSTANT_SPREAD` there, else None. Built as a ``homogeneous`` medium's, from
        ``sigma_t`` and the albedo as stored where the volume is constant (the values read back through float32
        interpolation differ in the last bits), so a constant volume renders as the homogeneous medium of its
        values."""
        import mitsuba as mi

        sigma_s, sigma_t = self._scene_coefficients(points_mm)
        albedo = np.divide(sigma_s, sigma_t, out=np.zeros_like(sigma_s), where=sigma_t > 0)
        values = [np.median(sigma_t, axis=0), np.median(albedo, axis=0)]
        if any(np.abs(a - v).max() > CONSTANT_SPREAD * max(np.abs(v).max(), 1e-300) for a, v in zip((sigma_t, albedo),
                                                                                                     values)):
            return None
        params = mi.traverse(self.medium)
        scale = float(params["scale"]) if "scale" in params else 1.0
        stored = self._stored("sigma_t")
        values[0] = values[0] if stored is None else stored * scale
        values[1] = np.minimum(values[1], 1.0) if (stored := self._stored("albedo")) is None else stored
        return Material.from_medium(values[0] / self.unit_mm, values[1], 1.0, self.g, eta, self.name)

    def coefficients(self, points_mm):
        """``(sigma_s', sigma_a)``, (N, 3) each in 1/mm, at ``points_mm`` (N, 3) in mm, world space."""
        if len(points_mm) == 0:
            return np.zeros((0, 3)), np.zeros((0, 3))
        sigma_s, sigma_t = (a / self.unit_mm for a in self._scene_coefficients(points_mm))
        return sigma_s * (1.0 - self.g), np.maximum(sigma_t - sigma_s, 0.0)

    def explored_coefficients(self, points_mm, normals):
        """``(sigma_s', sigma_a)`` (N, 3) each, 1/mm: the mean of the medium under each surface point (``normals``
        (N, 3) outward) weighted as its exitance is sensitive to it (Eq. H2): ``exp(-2 rho/l)`` in the distance
        ``rho`` up to :data:`COLUMN` diffusion lengths ``l`` of each channel, ``cos^2`` of the angle to the inward
        normal, ``l`` from the mean itself (two rounds, the first from the surface's coefficients). Points beyond
        the medium's box do not count."""
        points_mm, normals = (np.asarray(a, dtype=np.float64).reshape(-1, 3) for a in (points_mm, normals))
        out = np.zeros((2, len(points_mm), 3))
        if len(points_mm) == 0:
            return out[0], out[1]
        box = self._box(points_mm.mean(axis=0))
        for lo in range(0, len(points_mm), CHUNK):
            part = slice(lo, lo + CHUNK)
            out[:, part] = self._explored(points_mm[part], normals[part], box, lo)
        return out[0], out[1]

    def _box(self, inside_mm):
        """The medium's box (2, 3) in mm, from a point ``inside_mm`` (3,) within it (rays along the axes)."""
        axes = np.concatenate([np.eye(3), -np.eye(3)])
        _, far = self._box_exit(np.tile(inside_mm, (6, 1)), axes)
        return np.stack([inside_mm - far[3:], inside_mm + far[:3]])

    def _explored(self, points_mm, normals, box, first):
        """:meth:`explored_coefficients` of a few points (the temporaries are ``DEPTHS`` times their size), the
        ``first`` of them the whole set's; ``box`` the medium's box (2, 3)."""
        sigma_s_prime, sigma_a = self.coefficients(points_mm)
        n = len(points_mm)
        # DEPTHS lookups per point on a rank-1 lattice in (distance, cos^2 of the angle, azimuth), shifted per point
        j = (np.arange(DEPTHS) + 0.5) / DEPTHS
        shift = np.stack([((first + np.arange(n)) * g) % 1.0 for g in (0.6180339887, 0.7548776662)], axis=1)
        mu = (((j[None, :] * DEPTHS * 0.3819660113) + shift[:, :1]) % 1.0) ** (1.0 / 3.0)  # pdf 3 mu^2 on [0, 1]
        phi = 2.0 * np.pi * (((j[None, :] * DEPTHS * 0.5698402910) + shift[:, 1:]) % 1.0)
        tangent = np.cross(normals, np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        bitangent = np.cross(normals, tangent)
        sine = np.sqrt(np.maximum(1.0 - mu**2, 0.0))
        inward = (-mu[..., None] * normals[:, None, :] + (sine * np.cos(phi))[..., None] * tangent[:, None, :]
                  + (sine * np.sin(phi))[..., None] * bitangent[:, None, :])  # (n, DEPTHS, 3)
        for _ in range(2):
            length = 1.0 / np.sqrt(np.maximum(3.0 * sigma_a * (sigma_s_prime + sigma_a), 1e-300))
            length = np.minimum(length, COLUMN_CAP_MM)  # (n, 3)
            rho = COLUMN * length.max(axis=1, keepdims=True) * j  # (n, DEPTHS): one set of lookups for the channels
            at = points_mm[:, None, :] + inward * rho[..., None]
            inside = np.all((at >= box[0]) & (at <= box[1]), axis=2)
            s_at, a_at = (a.reshape(n, DEPTHS, 3) for a in self.coefficients(at.reshape(-1, 3)))
            weight = np.exp(-2.0 * rho[..., None] / length[:, None, :]) * inside[..., None]  # Eq. H2
            total = weight.sum(axis=1)  # (n, 3)
            seen = total > 0
            sigma_s_prime, sigma_a = (np.where(seen, np.einsum("njc,njc->nc", weight, a) / np.where(seen, total, 1.0),
                                               surface) for a, surface in ((s_at, sigma_s_prime), (a_at, sigma_a)))
        return sigma_s_prime, sigma_a

    def _box_exit(self, points_mm, directions):
        """Per point of ``points_mm`` (N, 3), whether it lies within the medium's box (Mitsuba's ``intersect_aabb``)
        and the distance in mm along its unit ``directions`` (N, 3) to the box's far side."""
        import mitsuba as mi

        p = (np.asarray(points_mm, dtype=np.float64) / self.unit_mm).T.astype(np.float32)
        ray = mi.Ray3f(mi.Point3f(*p), mi.Vector3f(*np.asarray(directions, dtype=np.float32).T))
        hit, mint, maxt = self.medium.intersect_aabb(ray)
        hit, mint, maxt = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (hit, mint, maxt))
        slack = 1e-5 * np.maximum(1.0, np.abs(p).max(axis=0))
        inside = (hit > 0) & (mint <= slack) & (maxt >= -slack)
        return inside, np.where(inside, np.maximum(maxt, 0.0) * self.unit_mm, 0.0)

    def inside(self, points_mm):
        """Which of ``points_mm`` (N, 3) lie within the medium's box."""
        return self._box_exit(points_mm, np.tile([1.0, 0.0, 0.0], (len(points_mm), 1)))[0]

    def check_cover(self, points_mm):
        """A one-line error where a surface point of ``points_mm`` (N, 3) lies outside the medium's box (Mitsuba's
        heterogeneous medium is empty there)."""
        outside = ~self.inside(points_mm)
        if outside.any():
            at = np.round(np.asarray(points_mm)[np.argmax(outside)] / self.unit_mm, 4).tolist()
            why = (" (Mitsuba takes a heterogeneous medium's box from its sigma_t volume, and a constvolume's is the "
                   "unit cube at the origin unless it has a to_world: give sigma_t a to_world that holds the shape, "
                   "or write a homogeneous medium where both are constant)"
                   if "sigma_t = ConstVolume" in str(self.medium) else
                   ": give the volumes a to_world that holds the whole shape")
            raise ConvsssError(f"translucent shape {self.name!r}: its heterogeneous medium's volume does not cover "
                               f"the object ({int(outside.sum())} of {len(outside)} surface points outside it, e.g. "
                               f"{at} in scene units){why}")

    def check_values(self, points_mm):
        """A one-line error where the coefficients at ``points_mm`` (N, 3) are not finite, negative or scatter more
        than they extinguish (an albedo above 1)."""
        sigma_s, sigma_t = (a.T for a in self._scene_coefficients(points_mm))
        points = np.asarray(points_mm, dtype=np.float64).T / self.unit_mm
        for label, bad in (("that are not finite", ~(np.isfinite(sigma_s) & np.isfinite(sigma_t))),
                           ("that are negative", (sigma_s < 0) | (sigma_t < 0)),
                           ("with an albedo above 1", sigma_s > sigma_t * (1 + 1e-6) + 1e-30)):
            if bad.any():
                c, i = np.unravel_index(np.argmax(bad), bad.shape)
                raise ConvsssError(f"translucent shape {self.name!r}: its heterogeneous medium has coefficients "
                                   f"{label} in channel {CHANNELS[c]} (sigma_t = {sigma_t[c, i]:.4g}, sigma_s = "
                                   f"{sigma_s[c, i]:.4g} at {np.round(points[:, i], 4).tolist()} in scene units)")

    def check(self, survey_mm, bbox_mm):
        """:meth:`check_cover` on the surface points ``survey_mm``, :meth:`check_values` on them and on a lattice of
        the object's box ``bbox_mm`` (its points inside the medium); returns the points checked."""
        self.check_cover(survey_mm)
        grid = lattice(bbox_mm)
        checked = np.concatenate([survey_mm, grid[self.inside(grid)]])
        self.check_values(checked)
        return checked

def check_albedo_grid(path):
    """A one-line error unless ``path`` is a Mitsuba grid volume file of 1 or 3 channels of finite values in [0, 1]
    (an albedo); its (z, y, x, channels) shape otherwise."""
    import mitsuba as mi

    try:
        grid = np.asarray(mi.VolumeGrid(str(path)), dtype=np.float64)
    except Exception as error:  # Mitsuba's reader raises RuntimeError with the reason on its last line
        reason = str(error).strip().splitlines()[-1] if str(error).strip() else type(error).__name__
        raise ConvsssError(f"volume {str(path)!r} is not a Mitsuba grid volume file (.vol): {reason}") from None
    grid = grid[..., None] if grid.ndim == 3 else grid  # one channel
    if grid.ndim != 4 or grid.shape[-1] not in (1, 3):
        raise ConvsssError(f"volume {str(path)!r} has {grid.shape[-1]} channels: an albedo volume has 1 or 3")
    bad = ~np.isfinite(grid) | (grid < 0) | (grid > 1)
    if bad.any():
        raise ConvsssError(f"volume {str(path)!r} has {int(bad.sum())} values outside [0, 1] or not finite (e.g. "
                           f"{grid[bad][0]!r}): an albedo lies in [0, 1]")
    return grid.shape


def lattice(bbox_mm, n=LATTICE):
    """``n^3`` points filling the box ``bbox_mm`` (2, 3), cell centres."""
    lo, hi = np.asarray(bbox_mm, dtype=np.float64)
    axes = [lo[c] + (np.arange(n) + 0.5) / n * (hi[c] - lo[c]) for c in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def _axis_coordinates(sigma_s_prime, sigma_a):
    """Per channel, the points ``q`` (N, 3, 2) of the module's docstring."""
    sigma_t_prime = sigma_s_prime + sigma_a
    albedo = sigma_s_prime / sigma_t_prime
    return np.stack([0.5 * np.log(np.maximum(1.0 - albedo, ABSORPTION_FLOOR)), -np.log(sigma_t_prime)], axis=-1)


def _material(q, eta, name):
    """The :class:`Material` of per-channel points ``q`` (3, 2)."""
    sigma_t_prime = np.exp(-q[:, 1])
    absorbed = np.exp(2.0 * q[:, 0])
    absorbed = np.where(absorbed <= ABSORPTION_FLOOR * (1 + 1e-9), 0.0, absorbed)
    return Material(sigma_t_prime * (1.0 - absorbed), sigma_t_prime * absorbed, eta, name)


@dataclass(frozen=True, eq=False)
class MediumClasses:
    """A heterogeneous medium as ``materials`` (K homogeneous classes) and the rule that splits any point between
    them (:meth:`weights`): per channel an axis through ``origin`` (3, 2) along ``direction`` (3, 2) with the nodes
    at coordinates ``nodes`` (3, K); ``mean`` the material at the axes' origin (the survey's mean point), what the
    object's single-material quantities read (the plan's summary, single scattering, the entry gain); ``shares``
    each class's share of the surface (its mean weight over the survey and the channels); ``table`` a k-d tree of
    surface points (M, 3) mm and their coordinates along the axes (M, 3), what :meth:`weights` reads (None: computed
    at each point)."""

    field: MediumField
    materials: tuple
    origin: np.ndarray
    direction: np.ndarray
    nodes: np.ndarray
    mean: Material = None
    shares: tuple = ()
    table: tuple = None

    def coordinates(self, points_mm, normals):
        """``(N, 3)``: per channel, the coordinate along its axis of the explored coefficients (Eq. H2) at the
        surface points ``points_mm`` (N, 3) of outward ``normals``."""
        if self.table is not None:
            tree, values = self.table
            distance, index = tree.query(np.asarray(points_mm, dtype=np.float64), k=TABLE_NEIGHBOURS, workers=-1)
            weight = 1.0 / np.maximum(distance, 1e-9) ** 2
            return np.einsum("nk,nkc->nc", weight, values[index]) / weight.sum(axis=1, keepdims=True)
        sigma_s_prime, sigma_a = self.field.explored_coefficients(points_mm, normals)
        bad = ~(np.isfinite(sigma_s_prime) & np.isfinite(sigma_a) & (sigma_s_prime + sigma_a > 0)).all(axis=1)
        if bad.any():  # what the survey and the lattice did not see (a defect smaller than their spacing)
            raise ConvsssError(f"translucent shape {self.field.name!r}: its heterogeneous medium has coefficients "
                               f"that are not finite, or neither scatter nor absorb, under {int(bad.sum())} of "
                               f"{len(bad)} surface points (e.g. at {np.round(points_mm[np.argmax(bad)], 4).tolist()} "
                               "mm)")
        return np.einsum("ncd,cd->nc", _axis_coordinates(sigma_s_prime, sigma_a) - self.origin, self.direction)

    def weights(self, points_mm, normals):
        """``(N, K, 3)`` class weights at the surface points ``points_mm`` (N, 3) of outward ``normals``, summing to
        1 over the classes per channel."""
        t = self.coordinates(points_mm, normals)
        count = self.nodes.shape[1]
        out = np.zeros((len(t), count, 3))
        if count == 1:
            out[:] = 1.0
            return out
        lo, hi = self.nodes[:, 0], self.nodes[:, -1]
        s = np.clip((t - lo) / np.where(hi > lo, hi - lo, 1.0), 0.0, 1.0) * (count - 1)
        j = np.minimum(np.floor(s).astype(int), count - 2)
        frac = s - j
        rows, channels = np.arange(len(t))[:, None], np.arange(3)[None, :]
        out[rows, j, channels] = 1.0 - frac
        out[rows, j + 1, channels] += frac
        return out


def medium_classes(field, survey_mm, normals, eta, inside_mm=(), surface=None, area_mm2=None):
    """The classes of ``field`` over the surface points ``survey_mm`` (N, 3) of outward ``normals`` (module
    docstring): a :class:`MediumClasses`, or the one :class:`Material` where the coefficients do not vary there nor
    at the points ``inside_mm`` (M, 3) (a constant surface over another core is not homogeneous). ``surface(count)``
    gives about ``count`` points spread over the surface of area ``area_mm2``, ``(points (n, 3) mm, outward normals
    (n, 3))``, for the table of :meth:`MediumClasses.weights` (None: no table)."""
    constant = field.constant(np.concatenate([survey_mm, np.reshape(inside_mm, (-1, 3))]), eta)
    if constant is not None:
        return constant
    sigma_s_prime, sigma_a = field.explored_coefficients(survey_mm, normals)
    empty = (sigma_s_prime + sigma_a) <= 0
    if empty.any():
        raise ConvsssError(f"translucent shape {field.name!r}: its heterogeneous medium neither scatters nor absorbs "
                           f"at {int(empty.any(axis=1).sum())} of {len(empty)} surface points (sigma_t = 0): an "
                           "object that is empty there is not translucent")
    q = _axis_coordinates(sigma_s_prime, sigma_a)  # (N, 3, 2)
    origin = q.mean(axis=0)
    direction = np.zeros((3, 2))
    spans = np.zeros((3, 2))
    for c in range(3):
        centred = q[:, c] - origin[c]
        _, _, vt = np.linalg.svd(centred, full_matrices=False)
        direction[c] = vt[0]
        t = centred @ vt[0]
        spans[c] = t.min(), t.max()
    count = int(min(MAX_CLASSES, 1 + max(math.ceil((hi - lo) / CLASS_STEP - 1e-9) for lo, hi in spans)))
    nodes = np.stack([np.linspace(lo, hi, count) for lo, hi in spans])
    classes = MediumClasses(field, (), origin, direction, nodes)
    weight = classes.weights(survey_mm, normals)  # (N, K, 3): each node's material follows the points near it
    materials = []
    for k in range(count):
        total = weight[:, k, :].sum(axis=0)  # (3,)
        mean = np.einsum("nc,ncd->cd", weight[:, k, :], q) / np.maximum(total, 1e-300)[:, None]
        on_axis = origin + nodes[:, k, None] * direction
        materials.append(_material(np.where(total[:, None] > 0, mean, on_axis), eta, f"{field.name} class {k}"))
    shares = tuple(float(f) for f in weight.mean(axis=(0, 2)))
    table = None
    if surface is not None:
        from scipy.spatial import cKDTree

        shortest = min(float(np.min(m.diffusion_length_mm)) for m in materials)
        points, outward = surface(int(np.clip(area_mm2 / (TABLE_SPACING * shortest) ** 2, *TABLE_POINTS)))
        table = (cKDTree(points), classes.coordinates(points, outward))
    return MediumClasses(field, tuple(materials), origin, direction, nodes, _material(origin, eta, field.name),
                         shares, table)
