"""What the camera sees: its view frame, a pixel's footprint, and which translucent objects are visible.

The convolution's layers are perpendicular to the camera's view axis and its cells are a pixel's footprint at the
object (paper §4.2, §5), so the renderer needs a projective camera (``perspective``, ``thinlens``,
``orthographic``). Which objects to build a transport for is decided by what the camera sees: one ray through
every pixel centre of the crop window; an object that none of them hits first is not rendered (a note says so),
whatever its bounding box does.
"""

from dataclasses import dataclass

import drjit as dr
import numpy as np

from ..backend import aligned, import_mitsuba, to_numpy3
from ..errors import ConvsssError
from ..samples import ViewFrame
from .traversal import hit_indices

mi = import_mitsuba()

#: Camera rays traced at once when finding what is visible.
RAYS_PER_BATCH = 1 << 20


def check_camera(sensor):
    """A one-line error unless ``sensor`` is a projective camera (the layers need an image plane) at a finite
    place."""
    if not isinstance(sensor, mi.ProjectiveCamera):
        raise ConvsssError(f"the convsss integrator renders through a camera (perspective, thinlens, orthographic); "
                           f"this scene's sensor is a {sensor.class_name()!r}")
    if not np.all(np.isfinite(np.array(sensor.world_transform().matrix, dtype=np.float64))):
        raise ConvsssError("the camera's transform is not finite (a translate, scale or look_at at infinity or NaN)")


def sensor_frame(sensor, unit_mm):
    """The camera's :class:`ViewFrame` in mm."""
    matrix = np.array(sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4)
    matrix[:3, 3] *= unit_mm
    return ViewFrame.from_matrix(matrix)


def pixel_footprint(sensor, frame, depth_mm, unit_mm):
    """Width (mm) of one pixel at view depth ``depth_mm``, from two rays through neighbouring film positions.

    Works for any projective sensor (perspective, thin lens, orthographic).
    """
    size = sensor.film().crop_size()
    centre = [0.5, 0.5]
    step = [0.5 + 1.0 / size[0], 0.5]
    points = []
    for position in (centre, step):
        ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(*position), mi.Point2f(0.5, 0.5))
        o = np.array(ray.o, dtype=np.float64).reshape(3) * unit_mm
        d = np.array(ray.d, dtype=np.float64).reshape(3)
        t = (depth_mm - frame.to_view(o[None])[0, 2]) / float(d @ frame.forward)
        points.append(o + t * d)
    return float(np.linalg.norm(points[1] - points[0]))


def pixel_centre_rays(sensor, first=0, rows=None):
    """One ray through the centre of each pixel of rows ``first`` .. ``first + rows`` (default: all) of the sensor's
    crop window: ``(rays, pixel)``, ``pixel`` the flat indices ``x + y * width`` (numpy int64).

    The camera's sample space spans the crop window, so pixel ``(x, y)`` of it is at ``((x + 0.5) / crop_width,
    (y + 0.5) / crop_height)``, as Mitsuba's integrators place it.
    """
    width, height = (int(n) for n in sensor.film().crop_size())
    last = height if rows is None else min(first + rows, height)
    y, x = np.mgrid[first:last, 0:width]
    u = aligned((x.ravel() + 0.5) / width, np.float32)  # aligned: the kernel reading them then does not vary
    v = aligned((y.ravel() + 0.5) / height, np.float32)
    rays, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(u, v), mi.Point2f(0.5, 0.5))
    dr.eval(rays)  # once: each numpy read of what they hit would trace them again
    return rays, (x + y * width).ravel()


@dataclass
class VisiblePoints:
    """Where one translucent object is the first surface seen, one ray per pixel centre of the crop window.

    Attributes
    ----------
    pixel : numpy.ndarray, shape (n,), int64    flat index ``x + y * width`` in the crop window
    position : numpy.ndarray, shape (n, 3)      the hit points in mm (float64)
    normal : numpy.ndarray, shape (n, 3)        the shape's geometric normals there (unit, as the mesh is oriented)
    depth : numpy.ndarray, shape (n,)           view depths in mm
    from_behind : numpy.ndarray, shape (n,)     whether the ray meets the surface from the side its normal points
                                                away from (``n . d > 0``)
    """

    pixel: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    depth: np.ndarray
    from_behind: np.ndarray


def first_hits(scene, sensor, frame, unit_mm, objects):
    """Where each object is the first surface seen, over one ray per pixel centre of the crop window.

    The rays are :func:`pixel_centre_rays`.

    Parameters
    ----------
    scene, sensor : mitsuba.Scene, mitsuba.Sensor
    frame : ViewFrame
    unit_mm : float
    objects : list of TranslucentObject
        The shapes asked about, each identified by its (instance, shape) registry indices.

    Returns
    -------
    list of VisiblePoints
        One per object (empty arrays: not visible).
    """
    crop = sensor.film().crop_size()
    found = [[] for _ in objects]
    rows = max(1, RAYS_PER_BATCH // int(crop[0]))
    for first in range(0, int(crop[1]), rows):
        ray, pixel = pixel_centre_rays(sensor, first, rows)
        si = scene.ray_intersect(ray)
        hit, indices, away = si.is_valid(), hit_indices(mi, si), dr.dot(si.n, ray.d) > 0
        dr.eval(hit, indices, si.p, si.n, away)  # one kernel, read below
        hit, away = hit.numpy(), away.numpy()
        shapes, instances = (a.numpy() for a in indices)
        position = to_numpy3(si.p, np.float64) * unit_mm
        normal = to_numpy3(si.n, np.float64)
        for chunks, obj in zip(found, objects):
            mine = hit & obj.hit(shapes, instances)
            chunks.append((pixel[mine], position[mine], normal[mine], away[mine]))
    out = []
    for chunks in found:
        pixel, position, normal, away = (np.concatenate(parts) for parts in zip(*chunks))
        out.append(VisiblePoints(pixel, position.reshape(-1, 3), normal.reshape(-1, 3), frame.to_view(
            position.reshape(-1, 3))[:, 2], away))
    return out
