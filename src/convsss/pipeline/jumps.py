"""Jumps across the deep interior: the random walk's shell tracing (Moon, Walter and Marschner 2007; Müller et al.
2016), for the walks of :mod:`.walk` inside large objects of high albedo (issue 60, item 4).

Deep inside such an object a walk wanders for hundreds of events before it nears the boundary, and none of them finds
light worth the time: every light is outside. From a scattering vertex ``x`` at least :data:`MARGIN` mean free paths
plus ``R`` from every surface, the walk crosses the ball of radius ``R`` around ``x`` in one step. The ball holds one
homogeneous medium of isotropic scattering, so the walk's exit from it, started by an isotropic scattering at its
centre, is known up to one table per channel: it leaves at a point uniform on the sphere (by symmetry), in a direction
whose cosine ``mu`` to the outward normal and whose weight follow

    f_i(mu) = U_i delta(1 - mu) + C_i(mu),     U_i = e^{-sigma_t,i R}                                     (Eq. J1)

in channel ``i``: the uncollided flight, which leaves along the normal, and the collided walks, ``C_i`` their
exits' albedo-weighted density in ``mu`` (:func:`exit_table`, by Monte Carlo on :data:`TABLE_PATHS` walks in
:data:`MU_BINS` bins of ``mu``; the azimuth about the normal uniform). ``T_i = U_i + int C_i`` is the share of the
light that leaves the ball at all. The hero channel ``h`` draws the exit: uncollided with odds ``U_h / T_h``, else
``mu`` from ``C_h / (T_h - U_h)``; channel ``j``'s density of the same exit is ``U_j / T_j`` or ``C_j(mu) / T_j``,
its contribution ``U_i`` or ``C_i(mu)`` (Eq. W1's ratios; the point's and the azimuth's densities are the same in
every channel and cancel). Exact but for the table's noise and bins: the walk's light is the same, with fewer events.

What a jump leaves out: the light sampled at the vertices inside the ball and at its centre (next-event
estimation; the centre's straight paths out of the ball are the jump's uncollided ones). A path that leaves the
object straight after a jump finds the light it hits with its whole weight, so an area light or an environment is
still found by the paths out of the ball; a delta light (point, spot, directional), which no path hits, loses what
those vertices would have sampled. Where light is sampled inside the object, the ball keeps ``MARGIN`` mean free
paths (in the channel of least extinction) inside every surface, so that each of its vertices' light is at most
``e^{-MARGIN}`` of a vertex's at the surface; the walks near the sphere's edge (about ``3 delta`` events per mean
free path ``delta`` below it, the diffusion Green's function of a sphere) add up to about ``3 e^{-MARGIN}`` of one
surface vertex's light per jump, below the table's noise. Where no light is sampled inside (:func:`margin`: a rough
dielectric boundary, which stops every shadow ray; a smooth one under environments left to the paths that hit
them) nothing is left out and the ball may reach the surface.

The ball's radius is the largest of :data:`RADII` mean free paths (of the channel of least extinction) that the
object's clearance allows: a lower bound of the distance to every surface, read at the nearest node of a grid of
the distance from each node to points that lie on the surfaces no further than ``spacing/2`` apart (a mesh's
triangles subdivided; another shape's parametrization on a grid; a sphere's or a rectangle's distance itself), less
what the grid's nodes can hide (:func:`clearance_grid`), over every surface that reaches the object's box. Jumps
are taken in an object that is the only one of its medium (a homogeneous one of isotropic scattering; an instanced
shape's medium is shared), closed, with no light but an environment within its box, and deep enough somewhere to
hold the least ball; elsewhere the walk is as before.
Measured (`auto`, 64² and 128², 64 spp, medians of 5 renders in one process, docs/benchmarks.md): the 40 mm potato
bunny behind glass under a uniform environment 1.17-1.27 times as fast (events per path 2.53 -> 1.87); forced to
walk (where `auto` keeps the transport), the 40 mm marble bunny behind glass under an area light 1.37-1.43, the
40 mm and a 100 mm whole-milk bunny under point lights 1.19-1.27 and 1.65-1.69; where a ball fits but walks never
reach it (the back-lit 40 mm skin1 bunny) 4-10 % slower.
"""

import math
from dataclasses import dataclass

import drjit as dr
import numpy as np

from ..backend import import_mitsuba
from ..jit import njit, prange
from ..splitmix import isotropic, uniform
from .interiors import medium_material, phase_g
from .traversal import emitter_bounds, instance_to_world, scene_surfaces, world_bbox

mi = import_mitsuba()

#: Mean free paths (of the channel of least extinction) kept between a ball and every surface: next-event
#: estimation inside the ball is left out, its light below ``3 e^{-MARGIN}`` of a surface vertex's (module doc).
MARGIN = 6.0
#: The balls' radii, in the same mean free paths: the largest the clearance allows is taken.
RADII = tuple(2.0 * 2.0 ** (k / 2.0) for k in range(9))  # 2 ... 32
#: Walks per channel in :func:`exit_table`, and bins of ``mu`` in its density.
TABLE_PATHS = 1 << 15
MU_BINS = 16
#: The clearance grids: at most this many nodes (all objects' together), cells no finer than a quarter mean free path.
MAX_CLEARANCE_NODES = 1 << 21
#: A walk asks for a ball from this many scattering events on: fewer have rarely gone deep enough (a ball's least
#: depth is a few mean free paths, some ``depth^2 / 2`` events), and a packet of lanes that ask for none skips the
#: lookup.
MIN_SCATTERINGS = 4
#: The most bytes :func:`table_folder` keeps (the oldest files go first), and the version of what it keeps (in every
#: file's key: a change to :func:`exit_table` or :func:`clearance_grid` must change it).
KEPT_BYTES = 256 << 20
FORMAT = "jumps-3"


@njit(parallel=True, cache=True)
def _exits(radii, albedo, paths, bins, seed):
    """Per walk and radius: the bin of ``mu`` where the walk first crossed the sphere (-2: uncollided, -1: ended by
    roulette before) and its weight ``albedo^n`` then (unit extinction, isotropic scattering, from the centre)."""
    k_count = radii.size
    where = np.full((paths, k_count), -1, dtype=np.int32)
    weight = np.zeros((paths, k_count))
    for i in prange(paths):
        state = np.uint64(seed) * np.uint64(0x632BE59BD9B4E019) + np.uint64(i) * np.uint64(0x9E3779B97F4A7C15)
        state, dx, dy, dz = isotropic(state)
        x = y = z = 0.0
        w, k, collided = 1.0, 0, False
        while k < k_count:
            state, u = uniform(state)
            t = -math.log(1.0 - u)
            b = x * dx + y * dy + z * dz
            c = x * x + y * y + z * z
            while k < k_count:
                s = -b + math.sqrt(max(b * b - c + radii[k] * radii[k], 0.0))
                if s > t:
                    break
                if collided:
                    mu = ((x + s * dx) * dx + (y + s * dy) * dy + (z + s * dz) * dz) / radii[k]
                    where[i, k] = min(int(mu * bins), bins - 1)
                    weight[i, k] = w
                else:
                    where[i, k] = -2
                k += 1
            if k == k_count:
                break
            x, y, z = x + t * dx, y + t * dy, z + t * dz
            collided = True
            w *= albedo
            if w < 0.1:  # Russian roulette
                state, u = uniform(state)
                if u >= 0.5:
                    break
                w *= 2.0
            state, dx, dy, dz = isotropic(state)
    return where, weight


def exit_table(radii, albedo, paths=TABLE_PATHS, bins=MU_BINS, seed=0):
    """Eq. J1's ``U`` and ``C`` for spheres of ``radii`` mean free paths of a medium of single-scattering ``albedo``
    (isotropic), lit by a scattering at the centre: ``(U (K,), C (K, bins))``, ``C[k, b]`` the collided walks'
    weight leaving in ``mu`` bin ``b`` (of width ``1/bins``). ``U = e^{-R}`` exactly; the collided part by Monte
    Carlo on ``paths`` walks, stratified: the collided share ``1 - U`` exactly times the weight per collided walk, so
    that at albedo 1 every walk leaves (``U + sum C = 1``)."""
    radii = np.asarray(radii, dtype=np.float64)
    where, weight = _exits(radii, float(albedo), int(paths), int(bins), int(seed))
    uncollided = np.exp(-radii)
    table = np.zeros((radii.size, bins))
    for k in range(radii.size):
        left = where[:, k] >= 0
        np.add.at(table[k], where[left, k], weight[left, k])
        table[k] *= (1.0 - uncollided[k]) / max(np.count_nonzero(where[:, k] != -2), 1)
    return uncollided, table


def _mesh_points(vertices, faces, spacing):
    """Points on a mesh's triangles (world), each triangle's lattice of ``n`` segments a side, ``n`` its longest edge
    over ``spacing`` (at most :data:`_MOST_SEGMENTS`): ``(points (P, 3), cover)``, every point of the surface within
    ``cover`` of one of them (a point of a triangle lies within its longest edge of each corner, here of a lattice
    triangle's)."""
    corners = vertices[faces]  # (F, 3, 3)
    edges = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).max(axis=1)
    segments = np.clip(np.ceil(edges / spacing), 1, _MOST_SEGMENTS).astype(np.int64)
    points, cover = [], float(np.max(edges / segments)) if len(edges) else 0.0
    for n in np.unique(segments):
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        a, b = i[keep] / n, j[keep] / n
        tri = corners[segments == n]
        points.append((tri[:, None, 0] + a[None, :, None] * (tri[:, None, 1] - tri[:, None, 0])
                       + b[None, :, None] * (tri[:, None, 2] - tri[:, None, 0])).reshape(-1, 3))
    return np.concatenate(points) if points else np.zeros((0, 3)), cover


_MOST_SEGMENTS = 256


def _shape_points(shape, to_world, spacing, lo, hi):
    """Points on ``shape`` placed by ``to_world`` near the box ``lo``-``hi`` and how far every point of it there may
    be from them (:func:`_mesh_points` for the triangles that reach the box; another shape's parametrization on a
    grid, the cover its cells' longest diagonal)."""
    from .surface import has_vertices, mesh_arrays

    if has_vertices(shape):
        vertices, faces = mesh_arrays(shape)
        world = vertices @ to_world[:3, :3].T + to_world[:3, 3]
        corners = world[faces]
        near = np.all((corners.max(axis=1) >= lo) & (corners.min(axis=1) <= hi), axis=1)
        return _mesh_points(world, faces[near], spacing)
    box = world_bbox(shape, to_world)
    n = int(np.clip(np.ceil(np.pi * float(np.max(box[1] - box[0])) / spacing), 8, 2048))
    u, v = np.meshgrid(np.linspace(0.0, 1.0, n + 1), np.linspace(0.0, 1.0, n + 1), indexing="ij")
    ps = shape.sample_position(0.0, mi.Point2f(u.ravel(), v.ravel()))
    local = np.stack([np.asarray(c) for c in ps.p], axis=1).astype(np.float64)
    grid = (local @ to_world[:3, :3].T + to_world[:3, 3]).reshape(n + 1, n + 1, 3)
    cover = max(float(np.linalg.norm(grid[1:, 1:] - grid[:-1, :-1], axis=2).max()),
                float(np.linalg.norm(grid[1:, :-1] - grid[:-1, 1:], axis=2).max()))
    return grid.reshape(-1, 3), cover


def _exact_distance(shape, to_world, axes):
    """The distance to ``shape`` placed by ``to_world`` at the grid points ``axes`` (three 1D arrays, sparse), where
    it is known in closed form: a sphere placed by a similarity, a rectangle of perpendicular sides; else None."""
    placed = to_world @ np.array(mi.traverse(shape)["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    linear, centre = placed[:3, :3], placed[:3, 3]
    x, y, z = np.meshgrid(*[a - c for a, c in zip(axes, centre)], indexing="ij", sparse=True)
    lengths = np.linalg.norm(linear, axis=0)
    if shape.class_name() == "Sphere":
        if not np.allclose(linear.T @ linear, lengths[0] ** 2 * np.identity(3), rtol=1e-6, atol=1e-12):
            return None  # an ellipsoid
        return np.abs(np.sqrt(x * x + y * y + z * z) - lengths[0])
    if shape.class_name() == "Rectangle" and abs(linear[:, 0] @ linear[:, 1]) <= 1e-9 * lengths[0] * lengths[1]:
        a, b = linear[:, 0] / lengths[0], linear[:, 1] / lengths[1]
        normal = np.cross(a, b)
        s, t = a[0] * x + a[1] * y + a[2] * z, b[0] * x + b[1] * y + b[2] * z
        h = normal[0] * x + normal[1] * y + normal[2] * z
        ds, dt = np.maximum(np.abs(s) - lengths[0], 0.0), np.maximum(np.abs(t) - lengths[1], 0.0)
        return np.sqrt(ds * ds + dt * dt + h * h)
    return None


_CLEARANCES = {}


def _digest(surfaces, lo, hi, spacing):
    """What :func:`clearance_grid` reads: each surface's vertices or parameters, its placement, the box, the spacing."""
    import hashlib

    from .surface import has_vertices, mesh_arrays

    h = hashlib.blake2b(np.asarray([*lo, *hi, spacing], dtype=np.float64).tobytes() + FORMAT.encode(), digest_size=16)
    for shape, to_world in surfaces:
        h.update(np.asarray(to_world, dtype=np.float64).tobytes())
        if has_vertices(shape):
            for array in mesh_arrays(shape):
                h.update(np.ascontiguousarray(array).tobytes())
        else:  # its class and points on it
            u, v = np.meshgrid(np.linspace(0.0, 1.0, 9), np.linspace(0.0, 1.0, 9), indexing="ij")
            points = shape.sample_position(0.0, mi.Point2f(u.ravel(), v.ravel())).p
            h.update(shape.class_name().encode() + np.stack([np.asarray(c) for c in points]).tobytes())
    return h.hexdigest()


def clearance(surfaces, lo, hi, spacing):
    """:func:`clearance_grid` as ``(nodes (mi.Float), origin, shape, deepest)``, kept for the process (a session's
    renders, one per seed, build their walks anew) and in :func:`table_folder` between processes (0.2-0.9 s to make,
    most of a small render's command)."""
    key = _digest(surfaces, lo, hi, spacing)
    if key not in _CLEARANCES:
        while len(_CLEARANCES) >= 4:
            _CLEARANCES.pop(next(iter(_CLEARANCES)))
        kept = _kept(f"clearance-{key}.npz", lambda: dict(zip(("values", "origin"), clearance_grid(
            surfaces, lo, hi, spacing))))
        values = np.asarray(kept["values"], dtype=np.float32)
        _CLEARANCES[key] = (mi.Float(values.ravel()), np.asarray(kept["origin"]), values.shape, float(values.max()))
    return _CLEARANCES[key]


def clearance_grid(surfaces, lo, hi, spacing):
    """A lower bound of the distance to the nearest of ``surfaces`` (``[(shape, to_world)]``) on the nodes of a grid
    of ``spacing`` over the box ``lo``-``hi`` (scene units, grown by two cells): ``(values (nx, ny, nz), origin)``,
    such that a node's value is at most the distance of every point nearer to it than to any other node. A node's
    distance to the nearest node that holds a surface point (Euclidean transform) less half a cell's diagonal (that
    point off its node) and the points' cover gives a bound at the node (a sphere's, a rectangle's: its distance
    itself), less half a cell's diagonal again a bound around it."""
    import scipy.ndimage

    origin = np.asarray(lo, dtype=np.float64) - 2.0 * spacing
    shape = tuple(int(s) for s in np.ceil((np.asarray(hi) + 2.0 * spacing - origin) / spacing).astype(int) + 1)
    held = np.zeros(shape, dtype=bool)
    cover, exact = 0.0, np.full(shape, np.inf)
    axes = [origin[k] + spacing * np.arange(shape[k]) for k in range(3)]
    far = origin + spacing * (np.array(shape) - 1)
    for surface, to_world in surfaces:
        known = None if surface.is_mesh() and surface.class_name() != "Rectangle" else _exact_distance(
            surface, to_world, axes)
        if known is not None:  # its distance itself
            exact = np.minimum(exact, known)
            continue
        points, gap = _shape_points(surface, to_world, spacing / 2.0, origin, far)
        cover = max(cover, gap)
        node = np.rint((points - origin) / spacing).astype(np.int64)
        inside = np.all((node >= 0) & (node < np.array(shape)), axis=1)
        held[tuple(node[inside].T)] = True
    if held.any():
        sampled = scipy.ndimage.distance_transform_edt(~held) * spacing - 0.5 * math.sqrt(3.0) * spacing - cover
        exact = np.minimum(exact, sampled)
    if not np.isfinite(exact).any():
        return np.zeros(shape), origin
    return exact - 0.5 * math.sqrt(3.0) * spacing, origin


@dataclass
class _Ball:
    """One object's jumps: its medium, its clearance (a Float per node of a grid of ``spacing`` from ``origin``, nodes
    ``shape``, read at the nearest node), the mean free path of its least extinction, the margin kept from the
    surface (in those), and where its tables start in :class:`Jumps`' arrays."""

    medium: object
    clearance: object
    origin: object
    spacing: float
    shape: tuple
    mfp: float
    margin: float
    count: int  # of RADII, those that fit somewhere
    offset: int


def _medium_of(obj, unit_mm):
    """``(sigma_t, albedo)`` per scene unit (``unit_mm`` mm) of ``obj``'s interior where jumps hold there (a
    homogeneous medium of isotropic scattering, a closed surface), else None."""
    medium = obj.shape.interior_medium()
    if (obj.classes is not None or not obj.closed or medium.class_name() != "HomogeneousMedium"
            or phase_g(mi.traverse(medium)) != 0.0):
        return None
    material = medium_material(mi, medium, obj.eta, unit_mm, obj.name)  # g = 0: the reduced coefficients are its own
    sigma_t = material.sigma_t_prime * unit_mm
    return (sigma_t, material.albedo_prime) if np.min(sigma_t) > 0.0 else None


_TABLES = {}


def table_folder():
    """Where :func:`exit_table`'s tables and the clearance grids are kept between processes: ``jumps`` in
    ``$CONVSSS_CACHE`` or ``~/.cache/convsss``."""
    import os
    from pathlib import Path

    return Path(os.environ.get("CONVSSS_CACHE") or Path.home() / ".cache" / "convsss") / "jumps"


def _kept(name, make):
    """The arrays ``make()`` returns (a dict of name: array), read from :func:`table_folder`'s file ``name`` where an
    earlier process made them, else made and written there (whole, or not at all: a read-only home makes them
    again next time)."""
    from ..errors import ConvsssError
    from ..files import atomic_write

    path = table_folder() / name
    try:
        with np.load(path) as kept:
            return {key: kept[key] for key in kept.files}
    except (OSError, KeyError, ValueError):
        pass
    made = make()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        files = sorted(path.parent.glob("*.npz"), key=lambda f: f.stat().st_mtime)
        while files and sum(f.stat().st_size for f in files) > KEPT_BYTES:  # the oldest go first
            files.pop(0).unlink(missing_ok=True)
        atomic_write(path, lambda tmp: np.savez(tmp, **made))
    except (OSError, ConvsssError):  # a read-only home: made again next time
        pass
    return made


def _channel_table(ratio, albedo, seed, count):
    """:func:`exit_table` for the first ``count`` of :data:`RADII` times ``ratio`` at ``albedo`` (0.2-0.6 s a
    channel for all of them), kept between processes (:func:`_kept`)."""
    import hashlib

    radii = np.asarray(RADII[:count]) * ratio
    key = hashlib.blake2b(repr((FORMAT, radii.tolist(), albedo, TABLE_PATHS, MU_BINS, seed)).encode(), digest_size=12)
    kept = _kept(f"exits-{key.hexdigest()}.npz", lambda: dict(zip(("uncollided", "collided"), exit_table(
        radii, albedo, seed=seed))))
    return kept["uncollided"], kept["collided"]


def _tables(sigma_t, albedo, count):
    """Eq. J1's ``T``, ``U`` (K, 3) and ``C`` (K, 3, bins) for balls of the first ``count`` of :data:`RADII` mean free
    paths of the least extinction in a medium of ``sigma_t`` and ``albedo`` (per channel), kept for the process (the
    walks of the tables stop at the largest: their cost grows as its square)."""
    key = (tuple(np.round(sigma_t / sigma_t.min(), 6).tolist()), tuple(np.round(albedo, 6).tolist()), count)
    if key not in _TABLES:
        us, cs = zip(*(_channel_table(ratio, a, c, count) for c, (ratio, a) in enumerate(zip(*key[:2]))))
        uncollided, collided = np.stack(us, axis=1), np.stack(cs, axis=1)
        _TABLES[key] = (uncollided + collided.sum(axis=2), uncollided, collided)
    return _TABLES[key]


def margin(scene, obj, environments):
    """The mean free paths kept between ``obj``'s balls and its surface (:data:`MARGIN`), 0 where no light is sampled
    inside it (module doc): behind a rough dielectric boundary, which stops shadow rays, and behind a smooth one
    under environments that Eq. W5 does not solve (``environments``: :func:`~.walk_shadows.solved_environments`)
    alone; None (no jumps) where a light other than an environment lies within its bounding box, or may (a light of
    no known place: :func:`~.traversal.emitter_bounds`)."""
    lo, hi = world_bbox(obj.shape, obj.to_world)
    for emitter in scene.emitters():
        bounds = emitter_bounds(mi, emitter)
        if bounds is None and not mi.has_flag(emitter.flags(), mi.EmitterFlags.Infinite):
            return None  # a light of no known place could lie inside
        if bounds is not None and np.all(bounds[1] >= lo) and np.all(bounds[0] <= hi):
            return None
    if obj.boundary == "roughdielectric":
        return 0.0
    flags = [e.flags() for e in scene.emitters()]
    dark = all(mi.has_flag(f, mi.EmitterFlags.Infinite) and not mi.has_flag(f, mi.EmitterFlags.Delta)
               and not any(e == s for s in environments) for f, e in zip(flags, scene.emitters()))
    return 0.0 if obj.boundary == "dielectric" and dark else MARGIN


class Jumps:
    """The jumps of the walks in ``objects`` of ``scene`` (module doc; ``unit_mm`` mm per scene unit), the
    ``environments`` Eq. W5 solves given; :meth:`fit` says where a ball fits, :meth:`sample` draws the jumps."""

    def __init__(self, scene, objects, unit_mm, environments=()):
        media = [mi.MediumPtr(obj.shape.interior_medium()) for obj in objects]
        shared = {k for k, m in enumerate(media) if sum(bool(dr.all(m == other)) for other in media) > 1}
        self.balls, totals, uncollideds, collideds = [], [], [], []
        for k, obj in enumerate(objects):
            found = None if k in shared else _medium_of(obj, unit_mm)
            kept = None if found is None else margin(scene, obj, environments)
            if kept is None:
                continue
            sigma_t, albedo = found
            mfp = 1.0 / float(sigma_t.min())
            lo, hi = world_bbox(obj.shape, obj.to_world)
            if 0.5 * float(np.min(hi - lo)) < (kept + RADII[0]) * mfp:
                continue  # too thin to hold the least ball anywhere
            budget = MAX_CLEARANCE_NODES / len(objects)  # the objects' grids together
            spacing = max(0.25 * mfp, float(np.prod(hi - lo) / budget) ** (1.0 / 3.0))
            surfaces = []
            for _, shape, instance in scene_surfaces(mi, scene):  # every surface that reaches its box
                to_world = instance_to_world(mi, instance)
                box = world_bbox(shape, to_world)
                if np.all(box[1] >= lo - 2.0 * spacing) and np.all(box[0] <= hi + 2.0 * spacing):
                    surfaces.append((shape, to_world))
            nodes, origin, shape, deepest = clearance(surfaces, lo, hi, spacing)
            count = sum((kept + r) * mfp <= deepest for r in RADII)  # the radii that fit somewhere
            if count == 0:
                continue
            total, uncollided, collided = _tables(sigma_t, albedo, count)
            self.balls.append(_Ball(media[k], nodes, mi.Vector3f(*origin.tolist()), spacing, shape, mfp,
                                    kept, count, sum(t.size for t in totals)))
            totals.append(total), uncollideds.append(uncollided), collideds.append(collided)
        if self.balls:
            collided = np.concatenate([c.reshape(-1, MU_BINS) for c in collideds])
            mass = collided.sum(axis=1, keepdims=True)
            cdf = np.cumsum(collided, axis=1) / np.where(mass > 0.0, mass, 1.0)
            cdf[:, -1] = 1.0
            self.total = mi.Float(np.concatenate([t.ravel() for t in totals]))
            self.uncollided = mi.Float(np.concatenate([u.ravel() for u in uncollideds]))
            self.density = mi.Float(collided.ravel() * MU_BINS)  # C per unit mu
            self.cdf = mi.Float(cdf.ravel())

    def __bool__(self):
        return bool(self.balls)

    @dr.syntax
    def fit(self, medium, p, active):
        """Per lane (``active`` in ``medium`` at ``p``): whether a ball fits, its radius (scene units) and its tables'
        first index (that of channel 0). A symbolic branch: a packet of lanes none of which asks skips it."""
        n = dr.width(p)
        fits, radius, index = dr.full(mi.Bool, False, n), dr.zeros(mi.Float, n), dr.zeros(mi.UInt32, n)
        if active:
            fits, radius, index = self._fit(medium, p, active)
        return fits, radius, index

    def _fit(self, medium, p, active):
        n = dr.width(p)
        fits, radius, index = dr.full(mi.Bool, False, n), dr.zeros(mi.Float, n), dr.zeros(mi.UInt32, n)
        for ball in self.balls:
            here = active & (medium == ball.medium)
            node = (mi.Vector3f(p) - ball.origin) / ball.spacing
            ix, iy, iz = (dr.clip(mi.Int32(dr.round(node[a])), 0, ball.shape[a] - 1) for a in range(3))
            cell = mi.UInt32((ix * ball.shape[1] + iy) * ball.shape[2] + iz)
            room = dr.gather(mi.Float, ball.clearance, cell, here) / ball.mfp - ball.margin
            k = dr.minimum(mi.Int32(dr.floor(2.0 * dr.log2(dr.maximum(room, 1e-6) / RADII[0]))), ball.count - 1)
            here &= k >= 0
            fits |= here
            radius[here] = RADII[0] * ball.mfp * dr.exp2(mi.Float(k) * 0.5)
            index[here] = ball.offset + 3 * mi.UInt32(dr.maximum(k, 0))
        return fits, radius, index

    @dr.syntax
    def sample(self, p, channel, sampler, fits, radius, index):
        """Jumps from the scattering vertices ``p`` where a ball fits (:meth:`fit`; hero ``channel``): ``(exit,
        direction, p, f)``, the point and direction the walk leaves the ball by, and Eq. J1's densities and
        contributions per channel (Color3f). A symbolic branch, as :meth:`fit`."""
        n = dr.width(fits)
        exit_point, direction = dr.zeros(mi.Point3f, n), dr.zeros(mi.Vector3f, n)
        pdf, f = dr.zeros(mi.Color3f, n), dr.zeros(mi.Color3f, n)
        if fits:
            exit_point, direction, pdf, f = self._drawn(p, channel, sampler, fits, radius, index)
        return exit_point, direction, pdf, f

    def _drawn(self, p, channel, sampler, jumped, radius, index):
        hero = index + channel
        uncollided = sampler.next_1d(jumped) * dr.gather(mi.Float, self.total, hero, jumped) < dr.gather(
            mi.Float, self.uncollided, hero, jumped)
        u = sampler.next_1d(jumped)
        first = hero * MU_BINS
        b = mi.UInt32(dr.binary_search(0, MU_BINS - 1, lambda i: dr.gather(mi.Float, self.cdf, first + i, jumped) <= u))
        mu = dr.select(uncollided, 1.0, (mi.Float(b) + sampler.next_1d(jumped)) / MU_BINS)
        pdf, f = dr.zeros(mi.Color3f, dr.width(p)), dr.zeros(mi.Color3f, dr.width(p))
        for c in range(3):  # Eq. J1 in each channel: density U_c / T_c or C_c(mu) / T_c, contribution U_c or C_c(mu)
            at = index + c
            total = dr.gather(mi.Float, self.total, at, jumped)
            f[c] = dr.select(uncollided, dr.gather(mi.Float, self.uncollided, at, jumped),
                             dr.gather(mi.Float, self.density, at * MU_BINS + b, jumped))
            pdf[c] = f[c] / total
        f[dr.gather(mi.Float, self.total, hero, jumped) <= 0.0] = 0.0  # a hero that leaves no light: no estimate
        normal = mi.warp.square_to_uniform_sphere(sampler.next_2d(jumped))
        phi = 2.0 * dr.pi * sampler.next_1d(jumped)
        sin_theta = dr.safe_sqrt(1.0 - dr.square(mu))
        direction = mi.Frame3f(normal).to_world(mi.Vector3f(sin_theta * dr.cos(phi), sin_theta * dr.sin(phi), mu))
        return mi.Point3f(p + radius * normal), direction, pdf, f
