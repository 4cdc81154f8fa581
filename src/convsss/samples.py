"""Irradiance samples and the view frame: what every transport takes in.

An :class:`IrradianceSamples` is a set of points on the whole surface of one translucent object (front and back),
each with its area ``A_i`` (mm^2), normal and irradiance ``E_i`` (paper Eq. 2, already multiplied by
``F_t(eta, w_i)``), so each carries the flux ``Phi_i = E_i A_i`` that the transports spread with the profile:
``M(x) = sum_i R_d(|x - x_i|) Phi_i`` (paper Eq. 1 without the outgoing Fresnel factor).

A :class:`ViewFrame` is the camera's orthonormal frame; the layers of the convolution transport are perpendicular to
its ``forward`` axis (paper §4.2: "parallel to the projection plane of the camera"). Lengths are in mm throughout.
"""

from dataclasses import dataclass

import numpy as np

from .errors import ConvsssError


def as_points(points, name="points"):
    """``points`` as a C-contiguous float64 array of shape (N, 3), or a one-line error.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Positions or directions (mm for positions); every value finite.
    name : str
        What the points are, for the error message.

    Returns
    -------
    numpy.ndarray, shape (N, 3), float64, C-contiguous
        The same values (a copy only where a conversion was needed).

    Raises
    ------
    ConvsssError
        For another shape, or NaN or infinite values.
    """
    arr = np.ascontiguousarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ConvsssError(f"{name} must have shape (N, 3), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConvsssError(f"{name} contain NaN or infinite values")
    return arr


@dataclass(frozen=True, eq=False)
class IrradianceSamples:
    """Points on a surface with area (mm^2) and irradiance ``E`` (RGB, any radiometric unit per mm^2).

    Attributes
    ----------
    position : (N, 3) float64, mm
    area : (N,) float64, mm^2, > 0 (a scalar is broadcast)
    irradiance : (N, 3) float64, >= 0
    normal : (N, 3) float64 or None, outward unit normals (for diagnostics; the transports do not need them)
    """

    position: np.ndarray
    area: np.ndarray
    irradiance: np.ndarray
    normal: np.ndarray | None = None

    def __post_init__(self):
        position = as_points(self.position, "sample positions")
        n = len(position)
        area = np.asarray(self.area, dtype=np.float64)
        area = np.ascontiguousarray(np.broadcast_to(area, (n,)) if area.ndim == 0 else area.reshape(-1))
        irradiance = np.ascontiguousarray(self.irradiance, dtype=np.float64)
        if irradiance.ndim == 1:
            irradiance = np.repeat(irradiance[:, None], 3, axis=1)
        if area.shape != (n,) or irradiance.shape != (n, 3):
            raise ConvsssError(f"samples: {n} positions need {n} areas and ({n}, 3) irradiance values, "
                               f"got {area.shape} and {irradiance.shape}")
        if not np.all(np.isfinite(area)) or np.any(area <= 0):
            raise ConvsssError("samples: every area must be finite and > 0")
        if not np.all(np.isfinite(irradiance)) or np.any(irradiance < 0):
            raise ConvsssError("samples: irradiance must be finite and >= 0")
        object.__setattr__(self, "position", position)
        object.__setattr__(self, "area", area)
        object.__setattr__(self, "irradiance", irradiance)
        if self.normal is not None:
            object.__setattr__(self, "normal", as_points(self.normal, "sample normals"))

    def __len__(self):
        return len(self.position)

    @property
    def flux(self):
        """``Phi_i = E_i A_i``, shape (N, 3) float64: the irradiance's unit times mm^2."""
        return self.irradiance * self.area[:, None]


class LocalIrradiance:
    """The irradiance of a set of samples read at any point of their surface: the area-weighted mean ``E`` of the
    ``neighbours`` nearest samples whose normal is within ``max_angle`` of the point's (the nearest sample alone
    when none is), the irradiance the transports spread there (paper Eq. 2, times ``F_t``), smoothed over about
    ``neighbours / sample_density`` layer cells.

    Parameters
    ----------
    samples : IrradianceSamples
        Positions in mm; without normals, every neighbour counts.
    neighbours : int
        Samples averaged per point.
    max_angle : float
        Degrees between a point's normal and a sample's beyond which the sample is on another side (a thin part's
        back, an edge's other face).

    Examples
    --------
    >>> s = IrradianceSamples(np.c_[np.arange(4.0), np.zeros((4, 2))], 1.0, np.arange(4.0))
    >>> LocalIrradiance(s, neighbours=2)(np.array([[0.4, 0.0, 0.0]]))[0]
    array([0.5, 0.5, 0.5])
    """

    def __init__(self, samples, neighbours=8, max_angle=60.0):
        from scipy.spatial import cKDTree

        self.samples = samples
        self.neighbours = max(1, min(int(neighbours), len(samples)))
        self.cos_limit = float(np.cos(np.radians(max_angle)))
        self._tree = cKDTree(samples.position)

    def __call__(self, points, normals=None):
        """``E`` (K, 3) at ``points`` (K, 3) mm, with their outward unit ``normals`` (K, 3) if known."""
        return self.average(self.samples.irradiance, points, normals)

    def average(self, values, points, normals=None):
        """The same mean of any per-sample ``values`` (N, ...) at ``points``: (K, ...)."""
        points = as_points(points)
        values = np.asarray(values)
        if len(points) == 0:
            return np.zeros((0, *values.shape[1:]))
        _, index = self._tree.query(points, k=self.neighbours, workers=-1)
        index = index.reshape(len(points), -1)
        weight = self.samples.area[index]
        if normals is not None and self.samples.normal is not None:
            normals = as_points(normals, "normals")
            facing = sum(normals[:, c, None] * self.samples.normal[index, c] for c in range(3))
            weight = np.where(facing >= self.cos_limit, weight, 0.0)
            weight[weight.sum(axis=1) == 0, 0] = 1.0  # none on this side: the nearest sample
        weight /= weight.sum(axis=1, keepdims=True)
        columns = values.reshape(len(values), -1)
        mean = np.stack([(weight * columns[index, c]).sum(axis=1) for c in range(columns.shape[1])], axis=1)
        return mean.reshape(len(points), *values.shape[1:])


@dataclass(frozen=True, eq=False)
class ViewFrame:
    """An orthonormal camera frame: ``origin`` and the axes ``right`` (x), ``up`` (y), ``forward`` (z, depth)."""

    origin: np.ndarray
    right: np.ndarray
    up: np.ndarray
    forward: np.ndarray

    def __post_init__(self):
        axes = np.array([self.right, self.up, self.forward], dtype=np.float64)
        if axes.shape != (3, 3) or not np.allclose(axes @ axes.T, np.eye(3), atol=1e-6):
            raise ConvsssError("view frame axes right, up, forward must be orthonormal")
        for name, value in zip(("right", "up", "forward"), axes):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "origin", np.asarray(self.origin, dtype=np.float64).reshape(3))

    @classmethod
    def look_at(cls, origin, target, up=(0.0, 1.0, 0.0)):
        """The frame of a camera at ``origin`` looking at ``target`` (``up`` need not be orthogonal).

        Parameters
        ----------
        origin, target : array_like, shape (3,)
            World positions (mm) of the camera and of the point it looks at; they must differ.
        up : array_like, shape (3,)
            A world direction that is to point up in the image; not parallel to the view direction.

        Returns
        -------
        ViewFrame
            With ``forward`` the unit vector from ``origin`` to ``target``, ``right = forward x up`` normalized and
            ``up`` made orthogonal to both.
        """
        origin = np.asarray(origin, dtype=np.float64)
        forward = np.asarray(target, dtype=np.float64) - origin
        if np.linalg.norm(forward) == 0:
            raise ConvsssError("view frame: origin and target coincide")
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(up, dtype=np.float64))
        if np.linalg.norm(right) < 1e-9:
            raise ConvsssError("view frame: the up vector is parallel to the view direction")
        right /= np.linalg.norm(right)
        return cls(origin, right, np.cross(right, forward), forward)

    @classmethod
    def from_matrix(cls, to_world):
        """From a 4x4 camera-to-world matrix in Mitsuba's convention (local +z forward, +y up, +x to the left).

        Parameters
        ----------
        to_world : array_like, shape (4, 4)
            The camera-to-world transform; its translation (the camera's position) in the frame's length unit (mm
            for the transports). Its columns 1 and 2 (up, forward) are normalized; scale is dropped.

        Returns
        -------
        ViewFrame
            ``origin`` the translation, ``forward`` and ``up`` the matrix's local +z and +y, ``right = forward x up``
            (Mitsuba's local -x).
        """
        m = np.asarray(to_world, dtype=np.float64)
        forward = m[:3, 2] / np.linalg.norm(m[:3, 2])
        up = m[:3, 1] / np.linalg.norm(m[:3, 1])
        return cls(m[:3, 3], np.cross(forward, up), up, forward)

    def to_view(self, points):
        """World points (N, 3) to view coordinates (x along right, y along up, z depth along forward).

        Parameters
        ----------
        points : array_like, shape (N, 3)
            World positions (mm).

        Returns
        -------
        numpy.ndarray, shape (N, 3), float64
            ``(points - origin)`` projected on ``right``, ``up`` and ``forward`` (mm).

        Examples
        --------
        >>> ViewFrame.look_at([0, 0, 10], [0, 0, 0]).to_view([[1.0, 2.0, 0.0]])
        array([[ 1.,  2., 10.]])
        """
        return _project(_as_rows(points), self.origin, self._axes())

    def rotate(self, vectors):
        """World directions (N, 3) to view axes: each projected on ``right``, ``up`` and ``forward``, (N, 3) float64."""
        return _project(_as_rows(vectors), np.zeros(3), self._axes())

    def _axes(self):
        return np.stack([self.right, self.up, self.forward])


def _as_rows(points):
    return np.ascontiguousarray(points, dtype=np.float64)


def _project(points, origin, axes):
    """``(points - origin)`` projected on the rows of ``axes`` (3, 3), elementwise (``@`` runs OpenBLAS on all
    threads, which then contend with the rest of the render for the cores; and a numba loop here would start numba's
    compiler in renders that need nothing else of it: 0.5 s of the command's start)."""
    d = points - origin
    return d[:, 0:1] * axes[:, 0] + d[:, 1:2] * axes[:, 1] + d[:, 2:3] * axes[:, 2]
