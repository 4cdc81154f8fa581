"""Exitance once per visible point: each object's ``M`` at the pixel centres where the camera sees it, read by Dr.Jit.

A render asks for the exitance ``M`` of paper Eq. 7 at every camera sample that lands on a translucent object (16
per pixel at 16 spp), and again where a bounce lands on it. ``M`` is smooth at the scale of the profile's core, so
asking the transport once per pixel is enough where the pixels resolve that scale: the transport is queried at the
pixel centres the object is seen at (:func:`~convsss.pipeline.camera.first_hits`), and a point ``x`` on the object is
given

    M(x) = sum_c w_c M(x_c),   w_c: bilinear weights of x's screen position among 4 pixel centres x_c,    (Eq. V1)

when all four centres ``x_c`` lie on the same object, on the same side of it (normals within ``MAX_NORMAL_ANGLE``)
and within ``reach`` of ``x`` in 3-D. The error of Eq. V1 is second order in the centres' spacing relative to the
profile's core width ``w`` (a linear ``M`` is reproduced exactly); ``reach = REACH * w``. Every other point (a
silhouette, a part of the object the camera does not see, a surface seen at a grazing angle, pixels too coarse for
the profile) is left to the transport itself.

The screen position of ``x`` is its projection by the camera (perspective, thin lens or orthographic), checked on the
pixel centres when the table is built: a camera whose projection does not give them back gets no table.
"""

import math

import drjit as dr
import numpy as np

from ..backend import aligned, import_mitsuba
from ..transport.multiscale import core_width

mi = import_mitsuba()

#: Centres farther than ``REACH`` core widths from the point looked up are not interpolated from (Eq. V1).
REACH = 2.0
#: Centres whose normal is farther than this from the point's (radians) are on another side of the object.
MAX_NORMAL_ANGLE = math.radians(30.0)
#: A projected pixel centre must land within this many pixels of where it is for the projection to be trusted.
PROJECTION_TOLERANCE = 1e-2


def world_to_pixel(sensor):
    """The camera's projection from world space to crop-window pixel coordinates (``(0.5, 0.5)``: the first pixel's
    centre), as a ``mitsuba.ProjectiveTransform4f``; None for a sensor that is not a perspective, thin-lens or
    orthographic camera."""
    film = sensor.film()
    size, crop, offset = film.size(), film.crop_size(), film.crop_offset()
    kind = sensor.class_name()
    if kind in ("PerspectiveCamera", "ThinLensCamera"):
        fov = float(mi.traverse(sensor)["x_fov"][0])
        to_sample = mi.perspective_projection(size, crop, offset, fov, 1e-2, 1e4)
    elif kind == "OrthographicCamera":
        to_sample = mi.orthographic_projection(size, crop, offset, 1e-2, 1e4)
    else:
        return None
    scale = mi.ScalarTransform4f().scale(mi.ScalarVector3f(float(crop[0]), float(crop[1]), 1.0))
    matrix = (np.array(scale.matrix, dtype=np.float64).reshape(4, 4)
              @ np.array(to_sample.matrix, dtype=np.float64).reshape(4, 4)
              @ np.linalg.inv(np.array(sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4)))
    return matrix


class ScreenExitance:
    """Each object's exitance at the pixel centres it is seen at, read back by Eq. V1 in Dr.Jit.

    Parameters
    ----------
    sensor : mitsuba.Sensor
    objects : list of TranslucentObject
    visible : list of VisiblePoints
        Per object, where the camera sees it (:func:`~convsss.pipeline.camera.first_hits`).
    transports : list
        Per object, its transport (``exitance(points_mm, normals) -> (n, 3)``).
    unit_mm : float

    Attributes
    ----------
    usable : bool
        False when the camera's projection could not be checked or no object's pixels resolve its profile: then
        :meth:`lookup` knows nothing.
    queries : int
        Transport queries made to build the table.
    """

    def __init__(self, sensor, objects, visible, transports, unit_mm):
        crop = sensor.film().crop_size()
        self.width, self.height = int(crop[0]), int(crop[1])
        count = self.width * self.height
        self.queries = 0
        matrix = world_to_pixel(sensor)
        self.usable = matrix is not None and self._projection_agrees(matrix, visible, unit_mm)
        owner = np.full(count, -1, dtype=np.int32)
        position = np.zeros((count, 3), dtype=np.float32)
        normal = np.zeros((count, 3), dtype=np.float32)
        exitance = np.zeros((count, 3), dtype=np.float32)
        reach = np.zeros(max(1, len(objects)), dtype=np.float32)
        for k, (obj, seen, transport) in enumerate(zip(objects, visible, transports)):
            if not self.usable or len(seen.pixel) == 0:
                continue
            reach[k] = REACH * max(core_width(profile) for profile in obj.profiles) / unit_mm
            owner[seen.pixel] = k
            position[seen.pixel] = seen.position / unit_mm
            normal[seen.pixel] = seen.normal
            exitance[seen.pixel] = transport.exitance(seen.position, seen.normal * obj.orientation)
            self.queries += len(seen.pixel)
        self._matrix = mi.ProjectiveTransform4f(mi.Matrix4f(matrix)) if self.usable else None
        # Aligned copies: the shading's kernel reads them, and their buffers' alignment is written into it.
        self._owner = mi.Int32(aligned(owner, np.int32))
        self._position = mi.Point3f(*(mi.Float(aligned(c, np.float32)) for c in position.T))
        self._normal = mi.Vector3f(*(mi.Float(aligned(c, np.float32)) for c in normal.T))
        self._exitance = mi.Color3f(*(mi.Float(aligned(c, np.float32)) for c in exitance.T))
        self._reach = mi.Float(aligned(reach, np.float32))

    def _projection_agrees(self, matrix, visible, unit_mm):
        """Whether ``matrix`` takes every visible pixel centre's hit point back to that pixel's centre."""
        for seen in visible:
            p = np.c_[seen.position / unit_mm, np.ones(len(seen.pixel))] @ matrix.T
            with np.errstate(divide="ignore", invalid="ignore"):
                uv = p[:, :2] / p[:, 3:4]
            centre = np.c_[seen.pixel % self.width, seen.pixel // self.width] + 0.5
            if not np.all(np.abs(uv - centre) <= PROJECTION_TOLERANCE):
                return False
        return True

    def lookup(self, si, which):
        """Eq. V1 at the lanes of ``si`` that hit object ``which`` (mi.Int32, -1: none): ``(M, known)``, the
        exitance (mi.Color3f) and where it is known (mi.Bool); elsewhere ``M`` is 0."""
        n = dr.width(si.p)
        known = (which >= 0) & self.usable
        if not self.usable:
            return dr.zeros(mi.Color3f, n), known
        screen = self._matrix @ si.p
        x, y = screen.x - 0.5, screen.y - 0.5
        x0, y0 = dr.floor(x), dr.floor(y)
        tx, ty = x - x0, y - y0
        # The table's size enters the kernel as an opaque value, so that another image size compiles nothing new.
        width, height = dr.opaque(mi.Int32, self.width), dr.opaque(mi.Int32, self.height)
        known &= (x0 >= 0) & (y0 >= 0) & (x0 + 1 < mi.Float(width)) & (y0 + 1 < mi.Float(height))
        base = dr.select(known, mi.Int32(x0) + mi.Int32(y0) * width, 0)
        reach = dr.gather(mi.Float, self._reach, mi.UInt32(dr.maximum(which, 0)), known)
        cos_limit = math.cos(MAX_NORMAL_ANGLE)
        value = dr.zeros(mi.Color3f, n)
        for dx, dy, w in ((0, 0, (1 - tx) * (1 - ty)), (1, 0, tx * (1 - ty)), (0, 1, (1 - tx) * ty), (1, 1, tx * ty)):
            corner = mi.UInt32(base + dx + dy * width)
            known &= dr.gather(mi.Int32, self._owner, corner, known) == which
            known &= dr.squared_norm(dr.gather(mi.Point3f, self._position, corner, known) - si.p) <= reach * reach
            known &= dr.dot(dr.gather(mi.Vector3f, self._normal, corner, known), si.n) >= cos_limit
            value += w * dr.gather(mi.Color3f, self._exitance, corner, known)
        return dr.select(known, value, 0.0), known

