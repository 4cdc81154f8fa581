"""The diffusion field the random walk ends in, where diffusion holds (:mod:`.walk`).

Deep inside an object of high albedo a walk runs to hundreds of events, and there diffusion is accurate. So each
object's fluence ``phi`` is solved on its own volume (Eq. D1 of :mod:`convsss.transport.volume`, lit by every
sample's irradiance: direct, indirect, from the other objects), and a walk that scatters at ``x``, at least
``walk_depth`` transport mean free paths ``1/sigma_t'`` below the surface, ends there in each channel whose reduced
albedo is at least :data:`DIFFUSIVE_ALBEDO` and whose diffusion length the grid resolves, adding what the diffusion
field scatters towards it. Diffuse radiance is ``L(x, w) = phi/(4 pi) + 3/(4 pi) E.w``, ``E = -D grad phi`` (Fick's
law, ``D = 1/(3 sigma_t')``); scattered by a phase function of mean cosine ``g`` towards ``w_o``:

    L_s(x, w_o) = (phi(x) - (g / sigma_t') grad phi(x) . w_o) / (4 pi).                                    (Eq. W3)

The walk stops at the scattering vertex with its weight times ``L_s`` (its in-scattered radiance): unbiased where
Eq. W3 is exact, and the channels not ended walk on. A part thinner than twice that depth has no point so deep,
so thin parts, ears and limbs and every event near the boundary are walked exactly.

Its extrapolated boundary ``z_b = 2 A D`` takes ``A`` from the boundary's Fresnel moments (d'Eon 2012, as the better
dipole), not the classic dipole's fit: behind a dielectric the fluence deep inside scales with ``z_r + z_b``, and
the classic ``A`` (3.96 against 3.63 at eta 1.5) made it too bright. On a 20 mm marble sphere behind glass under a
spherical light (32², against ``volpathmis`` at 2 x 2048 spp, whose seeds differ by 2 %; walks that never end in the
field read 0.986/1.000/1.014) walk_depth 2/4/8 read 1.05-1.08/1.03-1.05/1.01-1.035 with the classic ``A``,
1.02-1.05/1.01-1.04/1.00-1.03 with the moments'; under a null boundary the two are the same.

The field and the depth below the surface are one Dr.Jit texture per object (trilinear, on a grid of its own in the
camera's view frame, solved by the volume transport's :class:`~convsss.transport.volume.DiffusionSolve`): ``depth``
(mm; from the grid's signed distance near the surface, a distance transform deeper), ``phi`` and its gradient per
channel.
"""

import math
import warnings
from dataclasses import dataclass

import drjit as dr
import numpy as np

from ..backend import import_mitsuba, to_numpy3
from .interiors import phase_g

mi = import_mitsuba()

#: The least reduced albedo of a channel that a walk may end in the diffusion field (below, diffusion is poor).
DIFFUSIVE_ALBEDO = 0.8

#: The field's grid: cells per ``walk_depth`` transport mean free paths (its sources and a cell to spare lie above the
#: depth where walks end), and at most this many nodes (a coarser grid ends walks deeper only). On the 40 mm
#: whole-milk bunny at walk_depth 4 (128^2, 64 spp): 3 cells, the field in 5.0 s and means of 1.005/1.003/1.003 of
#: the reference; 2 cells, 1.7 s and 1.000/0.997/1.001 (the relative MSE alike).
CELLS_PER_DEPTH = 2.0
MAX_FIELD_NODES = 2e6
#: Bytes per node of the field beyond the solve's (:data:`~convsss.transport.volume.grid.BYTES_PER_NODE`): the fluence
#: and gradient (12 float64), the texture's data before and after its float32 copy (13 float64 + 13 float32).
FIELD_BYTES_PER_NODE = 12 * 8 + 13 * 8 + 13 * 4
#: Surface samples per face of a field cell (``h^2``) where the samples serve the field alone: its sources, and its
#: surface (:class:`~convsss.transport.volume.grid.Surface` keeps one per cube of side ``h/4``). On the 40 mm
#: whole-milk bunny at walk_depth 4 (128^2, 64 spp, R/G/B means over a 1024-spp reference): 2.1M samples (the
#: transport's rule) 1.005/1.005/1.006, 16 per face (496k) 1.005/1.004/1.005, 8 (248k) 1.005/1.003/1.003, 4 (124k)
#: 1.002/0.994/0.993, 2 (64k) 0.980/0.954/0.966.
FIELD_SAMPLES_PER_CELL = 8
#: The field's solves stop at this relative residual (the walk's estimate, not a slope read at the surface).
FIELD_TOLERANCE = 1e-5


@dataclass
class _ObjectField:
    """One object's field: its medium (what the walk compares), the texture and how to read it."""

    medium: object
    texture: object
    origin: np.ndarray  # the grid's first node, view frame (mm)
    spacing: float
    shape: tuple  # nodes along the view axes x, y, z
    frame: object  # ViewFrame, or None: the view frame is the world's
    mfp: np.ndarray  # 1/sigma_t' per channel (mm)
    usable: np.ndarray  # the channels a walk may end in
    shallowest: np.ndarray  # per channel, the least depth the grid's field holds at (mm): below its sources
    g: float


def _depth(sd, spacing):
    """Depth below the surface at the nodes (mm; < 0 outside) from the grid's signed distance, which is exact within
    its band and clamped beyond it: deeper, the band plus the distance (a Euclidean transform) to the band."""
    import scipy.ndimage

    band = -float(sd.min())
    deep = sd <= -band
    if not deep.any():
        return -sd
    return np.where(deep, band + spacing * scipy.ndimage.distance_transform_edt(deep), -sd)


def _object_field(obj, transport, spacing, note):
    """The :class:`_ObjectField` of ``obj`` from its ``transport``'s samples (Eq. D1 solved on a grid of
    ``spacing`` mm in the transport's view frame), or None when it has no channel to end walks in; ``note(text)``
    hears what it does next."""
    from ..profiles.diffusion import boundary
    from ..transport.volume import OPEN_DEPTH, DiffusionSolve, coefficients

    samples, frame, material = transport.samples, transport.frame, obj.material
    view = samples.position if frame is None else frame.to_view(samples.position)
    normal = samples.normal if frame is None else frame.rotate(samples.normal)
    k = coefficients(transport.profile, material, spacing, reflection=boundary(material.eta)[2])
    with np.errstate(divide="ignore"):
        grow = min(OPEN_DEPTH * float(np.max(1.0 / k.sigma_tr)), float(np.linalg.norm(np.ptp(view, axis=0))))
    note(f"its grid at {spacing:.3g} mm")
    solve = DiffusionSolve(view, normal, k, spacing, grow, timings=transport.timings,
                           advice="give a larger walk_depth, or walk_depth inf", what="the random walk's field")
    usable = solve.corrected & (material.albedo_prime >= DIFFUSIVE_ALBEDO)
    if not usable.any():
        return None
    note(f"solving {int(usable.sum())} channel(s) on {solve.sd.size:,} nodes")
    fields, _ = solve.solve(view, normal, samples.flux, tol=FIELD_TOLERANCE)
    phi, sd = solve.fluence(fields), solve.sd
    gradient = np.stack([np.stack(np.gradient(phi[..., c], spacing), axis=-1) for c in range(3)], axis=-2)
    data = np.concatenate([_depth(sd, spacing)[..., None], phi, gradient.reshape(*sd.shape, 9)], axis=-1)
    data = np.ascontiguousarray(np.transpose(data, (2, 1, 0, 3)), dtype=np.float32)  # Texture3f: z, y, x, channel
    medium = obj.shape.interior_medium()
    shallowest = k.source_depth - k.z_b + spacing
    return _ObjectField(mi.MediumPtr(medium), mi.Texture3f(mi.TensorXf(data)), solve.origin, spacing, sd.shape,
                        frame, 1.0 / material.sigma_t_prime, usable, shallowest, phase_g(mi.traverse(medium)))


def field_spacing(bounds_mm, material, walk_depth):
    """The field's grid spacing (mm): :data:`CELLS_PER_DEPTH` cells per ``walk_depth`` of the shortest transport mean
    free path, no coarser than the volume transport's own (:func:`~convsss.transport.volume.auto_spacing`), no finer
    than :data:`MAX_FIELD_NODES` nodes over ``bounds_mm`` allow."""
    from ..transport.volume import auto_spacing

    lo, hi = np.asarray(bounds_mm, dtype=np.float64)
    size = np.maximum(hi - lo, 1e-9)
    finest = float(np.prod(size) / MAX_FIELD_NODES) ** (1.0 / 3.0)
    wanted = walk_depth * float(np.min(1.0 / material.sigma_t_prime)) / CELLS_PER_DEPTH
    return max(min(wanted, auto_spacing(material, float(np.max(size)))), finest)


class CoarseFieldWarning(UserWarning):
    """The field's grid, at its node cap, is far coarser than ``walk_depth`` asks: walks end much deeper, or never."""


def _check_resolution(obj, spacing, walk_depth):
    """Warn (:class:`CoarseFieldWarning`) where the grid's cells are over :data:`CELLS_PER_DEPTH` times coarser than
    ``walk_depth`` asks (a large object: at most :data:`MAX_FIELD_NODES` nodes): walks end only about a cell deep."""
    asked = walk_depth * float(np.min(1.0 / obj.material.sigma_t_prime))
    if spacing > CELLS_PER_DEPTH * asked:
        warnings.warn(CoarseFieldWarning(
            f"translucent shape {obj.name!r}: the diffusion field's grid (at most {MAX_FIELD_NODES:.0e} nodes) has "
            f"{spacing:.3g} mm cells, so walks end in it only about {spacing:.3g} mm deep, not {asked:.3g} mm "
            f"(walk_depth {walk_depth:g}): most walk to their end; walk_depth 0 (the transport) or auto suits an "
            "object this large"), stacklevel=3)


def field_only(params, mode):
    """Whether the surface samples serve the field alone: walks end in it (``mode``, a
    :class:`~.params.RenderMode`: every camera path walks, so no pixel reads a transport's exitance) and no AOV asks
    for the transports' exitance or the samples' irradiance."""
    from .params import reads_transports

    return mode.field and not reads_transports(params.aovs)


def sample_count(obj, params, mode):
    """The surface samples ``obj``'s field asks for (:data:`FIELD_SAMPLES_PER_CELL` per face of its cells), or None
    where the samples serve more than the field (:func:`field_only`) or the object has no field (a medium of
    classes): the transports' own rules hold there."""
    if not field_only(params, mode) or obj.classes is not None:
        return None
    h = field_spacing(obj.bbox_mm, obj.material, mode.walk_depth)
    return max(int(math.ceil(FIELD_SAMPLES_PER_CELL * obj.area_mm2 / h**2)), 1)


def planned_bytes(obj, mode):
    """The bytes ``obj``'s field will hold (its grid's system and solver, the fluence, gradient and texture), 0
    where ``walk_depth`` makes none: for the plan's memory check, before any work."""
    from ..transport.volume.grid import BYTES_PER_NODE

    if not mode.field or obj.classes is not None:
        return 0
    lo, hi = np.asarray(obj.bbox_mm, dtype=np.float64)
    h = field_spacing(obj.bbox_mm, obj.material, mode.walk_depth)
    nodes = float(np.prod(np.floor((hi - lo) / h) + 8))  # the domain's padding: z_b and two cells a side, about
    return int(nodes * (BYTES_PER_NODE + FIELD_BYTES_PER_NODE))


def diffusion_field(objects, transports, mode, unit_mm, note=lambda text: None):
    """The fields of ``objects`` (:class:`DiffusionField`) from their ``transports``' samples (their irradiance,
    profile and view frame); None where ``walk_depth`` is 0 or inf, or no object has a field (a heterogeneous
    interior has none: its walks go on to their end). ``note(text)`` hears each step (the progress display: a field
    takes seconds to minutes)."""
    if not mode.field:
        return None
    fields = []
    for k, (obj, transport) in enumerate(zip(objects, transports)):
        if transport is None or obj.classes is not None or not len(transport.samples):
            continue

        def step(text, k=k, obj=obj):
            note(f"the field of {obj.name!r} ({k + 1}/{len(objects)}): {text}")

        spacing = field_spacing(obj.bbox_mm, obj.material, mode.walk_depth)
        _check_resolution(obj, spacing, mode.walk_depth)
        made = _object_field(obj, transport, spacing, step)
        if made is not None:
            fields.append(made)
    return DiffusionField(fields, mode.walk_depth, unit_mm) if fields else None


class DiffusionField:
    """The objects' fields (module doc) and the rule that ends a walk in them."""

    def __init__(self, fields, walk_depth, unit_mm):
        self.fields, self.walk_depth, self.unit_mm = fields, float(walk_depth), float(unit_mm)

    def ending(self, mei, medium, scatter):
        """At the scattering vertices ``mei`` (lanes ``scatter``) in ``medium``: which channels end there (Color3f,
        1 or 0) and the radiance the field scatters towards ``mei.wi`` (Eq. W3; 0 in the other channels)."""
        n = dr.width(mei.p)
        ends = dr.zeros(mi.Color3f, n)
        radiance = dr.zeros(mi.Color3f, n)
        for f in self.fields:
            here = scatter & (medium == f.medium)
            depth, phi, gradient, w = self._read(f, mei.p, mei.wi, here)
            for c in range(3):
                if not f.usable[c]:
                    continue
                deep = here & (depth >= max(self.walk_depth * float(f.mfp[c]), float(f.shallowest[c])))
                slope = dr.dot(gradient[c], w)
                scattered = dr.maximum(phi[c] - f.g * float(f.mfp[c]) * slope, 0.0) / (4.0 * dr.pi)  # Eq. W3
                ends[c] = dr.select(deep, 1.0, ends[c])
                radiance[c] = dr.select(deep, scattered, radiance[c])
        return ends, radiance

    def fluence(self, index, points):
        """Object ``index``'s (in the order of the fields) depth below the surface (K,) and fluence (K, 3) at world
        ``points`` (K, 3; scene units), numpy: what the walks read."""
        f = self.fields[index]
        p = mi.Point3f(*np.ascontiguousarray(np.asarray(points, dtype=np.float32).T))
        depth, phi, _, _ = self._read(f, p, dr.zeros(mi.Vector3f, len(points)), True)
        return depth.numpy().astype(np.float64), to_numpy3(phi, np.float64)

    def _read(self, f, points, directions, active):
        """Field ``f`` at world ``points`` (scene units): depth (mm), fluence (Color3f), its gradient per channel
        (three Vector3f, view frame, per mm), and ``directions`` in the view frame."""
        p = mi.Vector3f(points) * self.unit_mm
        w = mi.Vector3f(directions)
        if f.frame is not None:
            axes = [mi.Vector3f(*np.asarray(a, dtype=np.float64).tolist()) for a in (f.frame.right, f.frame.up,
                                                                                      f.frame.forward)]
            p = p - mi.Vector3f(*np.asarray(f.frame.origin, dtype=np.float64).tolist())
            p = mi.Vector3f(dr.dot(p, axes[0]), dr.dot(p, axes[1]), dr.dot(p, axes[2]))
            w = mi.Vector3f(dr.dot(w, axes[0]), dr.dot(w, axes[1]), dr.dot(w, axes[2]))
        node = (p - mi.Vector3f(*f.origin.tolist())) / f.spacing
        uv = mi.Point3f((node.x + 0.5) / f.shape[0], (node.y + 0.5) / f.shape[1], (node.z + 0.5) / f.shape[2])
        values = f.texture.eval(uv, active)
        gradient = [mi.Vector3f(values[4 + 3 * c], values[5 + 3 * c], values[6 + 3 * c]) for c in range(3)]
        return values[0], mi.Color3f(values[1], values[2], values[3]), gradient, w
