"""A surface colour from a texture: a ``convsss_medium`` whose ``color`` (and ``mfp_mm``) is a texture on its shape,
made as the heterogeneous medium it stands for.

What it means physically: a medium whose coefficients vary along the surface and are constant with depth. At a
point ``y`` inside the object they are those of the nearest point ``x`` of the object's surface, whose colour (the
texture at its texture coordinates, Mitsuba's filtering and wrapping) is inverted as a constant colour is
(:func:`~convsss.profiles.models.material_from_color`, under the medium's ``model`` and ``eta``):

    alpha'(y) = A(C(uv(x))),   sigma_t'(y) = 1 / mfp(uv(x)),   x = argmin_{x on the surface} |y - x|     (Eq. T1)

``A`` the inverse of the model's total reflectance (:func:`~convsss.profiles.models.albedos_from_reflectances`).
Where the colour varies slowly over a few diffusion lengths, a point's light is what a homogeneous object of its
colour gives, the colour the artist painted; across a sharp edge of the texture light diffuses from one side into
the other, as it does in the ``volpathmis`` render of the same medium.

The medium is made as a ``heterogeneous`` medium whose ``albedo`` (and ``sigma_t``, where ``mfp_mm`` is a texture)
is a ``gridvolume`` over the shape's bounding box (:func:`equivalent_medium`): :data:`GRID_CELLS` cells along its
longest side; a cell the surface crosses takes Eq. T1 at the surface point nearest its centre (of a dense set), any
other cell the value of its nearest such cell (within a cell of Eq. T1's nearest point). The scene is loaded again
with it (:func:`~convsss.scene.loading.load_scene`), so that convsss renders it through :mod:`convsss.pipeline.media`
as any heterogeneous interior, and ``volpathmis`` (``convsss reference``) renders the very same medium as ground truth.
Detail of the texture finer than a cell is blurred over a cell (a 20 mm object: 0.2 mm), and the surface's colour
is read from the grid by trilinear interpolation.
"""

import numpy as np

from ..errors import ConvsssError
from ..media.dicts import medium_parameters
from ..media.named import forget, named_medium_of, texture_values
from ..pipeline.surface import surface_square
from ..pipeline.traversal import scene_surfaces, world_bbox
from ..profiles.models import albedos_from_reflectances

#: Cells of the grid along the box's longest side (each other side in proportion, at least 2).
GRID_CELLS = 96
#: Surface points per cell of the grid's cross-section (``extent^2 / cell^2``), at most :data:`MAX_SURFACE_POINTS`.
POINTS_PER_CELL = 8
MAX_SURFACE_POINTS = 1 << 20


def textured_media(mi, scene):
    """The textured ``convsss_medium`` interiors of ``scene``: per medium's key, ``(NamedMedium, [(name, shape)])``;
    a one-line error for one in a shapegroup, or on a mesh without texture coordinates."""
    found = {}
    for name, shape, instance in scene_surfaces(mi, scene):
        named = named_medium_of(mi, shape.interior_medium())
        if named is None or not named.textured:
            continue
        if instance is not None:
            raise ConvsssError(f"translucent shape {name!r}: a textured convsss_medium in a shapegroup is not "
                               "supported (its volume would be one for every instance): give each object its shape")
        if isinstance(shape, mi.Mesh) and not shape.has_vertex_texcoords():
            raise ConvsssError(f"translucent shape {name!r} has no texture coordinates (uv), so its convsss_medium's "
                               "texture has nowhere to go: give the mesh uv coordinates, or a constant colour")
        found.setdefault(named.key, (named, []))[1].append((name, shape))
    return found


def _surface_points(named, shapes, count):
    """``(positions (N, 3) in scene units, sigma_s' (N, 3), sigma_t' (N, 3) in 1/mm)`` at about ``count`` points
    spread over ``shapes`` in proportion to their areas (Eq. T1 at each)."""
    areas = np.array([float(np.asarray(shape.surface_area()).reshape(-1)[0]) for _, shape in shapes])
    positions, albedos, mfps = [], [], []
    for (name, shape), area in zip(shapes, areas):
        u = surface_square(shape, max(int(count * area / areas.sum()), 1024), seed=0)
        ps = shape.sample_position(0.0, u)
        uv = np.asarray(ps.uv, dtype=np.float64).reshape(2, -1).T
        positions.append(np.asarray(ps.p, dtype=np.float64).reshape(3, -1).T)
        color = np.broadcast_to(named.color, uv.shape[:1] + (3,)) if named.color_texture is None else (
            texture_values(named.color_texture, uv))
        albedos.append(albedos_from_reflectances(named.model, color, named.eta,
                                                 f"translucent shape {name!r}: its convsss_medium's color texture"))
        mfp = np.broadcast_to(named.mfp_mm, color.shape) if named.mfp_texture is None else (
            texture_values(named.mfp_texture, uv))
        if not (np.all(np.isfinite(mfp)) and np.all(mfp > 0)):
            raise ConvsssError(f"translucent shape {name!r}: its convsss_medium's mfp_mm texture is not finite and "
                               f"> 0 everywhere on it (e.g. {mfp[~(np.isfinite(mfp) & (mfp > 0))][0]!r})")
        mfps.append(mfp)
    albedo, mfp = np.concatenate(albedos), np.concatenate(mfps)
    return np.concatenate(positions), albedo / mfp, 1.0 / mfp


def equivalent_medium(mi, named, shapes):
    """The Mitsuba ``heterogeneous`` medium dictionary (isotropic phase) that the textured ``named`` medium of
    ``shapes`` (``[(name, shape)]``, plain shapes) stands for (Eq. T1, module docstring), in scene units."""
    from scipy.ndimage import distance_transform_edt
    from scipy.spatial import cKDTree

    boxes = np.array([world_bbox(shape, np.identity(4)) for _, shape in shapes])
    low, high = boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)
    cell = float((high - low).max()) / (GRID_CELLS - 2)  # a cell of margin on each side of the longest
    low, high = low - cell, high + cell
    cells = np.maximum(np.ceil((high - low) / cell).astype(int), 2)  # (x, y, z)
    high = low + cells * cell
    count = min(int(POINTS_PER_CELL * GRID_CELLS**2), MAX_SURFACE_POINTS)
    points, sigma_s_prime, sigma_t_prime = _surface_points(named, shapes, count)
    # The cells the surface crosses take their centre's nearest surface point; every other cell the value of its
    # nearest such cell (a Euclidean distance transform: within a cell of Eq. T1's nearest point, at a cost linear
    # in the cells).
    shape = tuple(cells[::-1])  # (z, y, x), as a gridvolume holds its data
    crossed = np.zeros(shape, dtype=bool)
    index = np.clip(((points - low) / cell).astype(int), 0, cells - 1)[:, ::-1]
    crossed[tuple(index.T)] = True
    zyx = np.argwhere(crossed)
    _, nearest_point = cKDTree(points).query(low + (zyx[:, ::-1] + 0.5) * cell, workers=-1)
    owner = np.full(shape, -1, dtype=np.int64)
    owner[tuple(zyx.T)] = nearest_point
    nearest_cell = distance_transform_edt(~crossed, return_distances=False, return_indices=True)
    nearest = owner[tuple(nearest_cell)].reshape(-1)
    albedo = (sigma_s_prime / sigma_t_prime)[nearest].reshape(*shape, 3)
    to_world = mi.ScalarTransform4f().translate(low.tolist()).scale((high - low).tolist())
    if named.mfp_texture is None:  # one extinction: the homogeneous medium's own values, as medium_dict writes them
        own = medium_parameters(named.material, named.unit_mm)
        scale = own["scale"]
        extinction = {"type": "constvolume", "value": {"type": "rgb", "value": own["sigma_t"].tolist()},
                      "to_world": to_world}
    else:
        sigma_t = sigma_t_prime[nearest] * named.unit_mm  # per scene unit
        scale = float(sigma_t.max())
        extinction = {"type": "gridvolume", "to_world": to_world,
                      "data": mi.TensorXf((sigma_t / scale).reshape(albedo.shape).astype(np.float32))}
    return {"type": "heterogeneous", "scale": scale, "sigma_t": extinction,
            "albedo": {"type": "gridvolume", "data": mi.TensorXf(albedo.astype(np.float32)), "to_world": to_world}}


def equivalent_media(mi, scene):
    """Per textured ``convsss_medium`` of ``scene`` (:func:`textured_media`), its key -> :func:`equivalent_medium`;
    the placeholders ``scene`` holds are forgotten (:func:`~.presets.forget`: the scene is to be loaded again with
    the equivalents, and a medium made later at one of their addresses is not theirs)."""
    found = textured_media(mi, scene)
    media = {key: equivalent_medium(mi, named, shapes) for key, (named, shapes) in found.items()}
    for _, shapes in found.values():
        for _, shape in shapes:
            forget(shape.interior_medium())
    return media
