"""Where the surface path tracer reads the transports' exitance ``M`` (paper Eq. 7): the screen table at the pixel
centres the objects are seen at (:mod:`.screen`, Eq. V1), the objects' mesh tables (:mod:`.mesh_exitance`, Eq. V2)
and the transports themselves, in numpy, for the hits the path tracer's loop recorded (:mod:`.path_tracer`); and the
hits of paths traced before any transport exists, resolved once the transports are built (:mod:`.passes`).
"""

import drjit as dr
import numpy as np

from ..backend import aligned, import_mitsuba
from .mesh_exitance import MeshExitance, usable

mi = import_mitsuba()

#: Room for recorded hits (:class:`HitRecords`), per path; more take a second, identical trace.
RECORD_ROOM = 1.0


def _color(array):
    """(K, 3) numpy -> mi.Color3f (aligned copies, :func:`~convsss.backend.aligned`)."""
    a = np.asarray(array, dtype=np.float32).T
    return mi.Color3f(*(mi.Float(aligned(c, np.float32)) for c in a))


class HitRecords:
    """The hits on translucent objects whose ``M`` a kernel's paths need (:meth:`ExitanceLookups.add_recorded`): per
    hit the object, point, normal, weight ``beta (1/pi) F_t`` (paper Eq. 7 without ``M``), lane, whether it is a
    camera ray's first hit, and the face it is on. Room for ``room`` of them (:data:`RECORD_ROOM` per lane of a kernel
    of ``lanes`` paths): a kernel that records more (:attr:`count`) is traced again with room for all (its sampler
    copied before)."""

    def __init__(self, lanes, room=None):
        self.room = max(1, int(RECORD_ROOM * lanes)) if room is None else room
        # Uninitialized: only the first ``count`` are written and read, so the rest is never touched (zeroing room
        # for every lane would write all of it on every render, for nothing).
        self.records = tuple(dr.empty(t, self.room) for t in (mi.Int32, mi.Point3f, mi.Vector3f, mi.Color3f,
                                                               mi.UInt32, mi.Bool, mi.UInt32))
        self.recorded = dr.zeros(mi.UInt32, 1)

    def add(self, asked, values):
        """Append ``values`` (per lane, in :attr:`records`' order) of the ``asked`` lanes, counting them all and keeping
        the first :attr:`room` (opaque: the kernel outlives the image's size)."""
        slot = dr.scatter_inc(self.recorded, mi.UInt32(0), asked)
        kept = asked & (slot < dr.opaque(mi.UInt32, self.room))
        for record, value in zip(self.records, values):
            dr.scatter(record, value, slot, kept)

    @property
    def count(self):
        """Hits recorded, kept or not (after the kernel ran)."""
        return int(self.recorded.numpy()[0])

    @staticmethod
    def traced(trace, sampler, lanes):
        """``(trace(sampler, hits), hits)``: a kernel of ``lanes`` paths recording its hits in ``hits``, traced again
        from a copy of ``sampler`` (the same paths) with room for all of them where more were recorded than there was
        room for."""
        hits = HitRecords(lanes)
        while True:
            replay = sampler.clone()
            out = trace(sampler, hits)
            if hits.count <= hits.room:
                return out, hits
            sampler, hits = replay, HitRecords(0, hits.count)


class ExitanceLookups:
    """The exitance the path tracer of ``objects`` reads (module doc); ``unit_mm`` mm per scene unit, ``stop()``
    asked between chunks of queries (Ctrl-C: the chunks left stay 0)."""

    def __init__(self, objects, unit_mm, stop=None):
        self.objects, self.unit_mm, self.stop = objects, unit_mm, stop
        self.attach([None] * len(objects))

    def attach(self, transports, screen=None):
        """Read ``M`` from ``transports`` from now on: one per object (``exitance(points_mm) -> (K, 3)``), or
        ``None`` for an object whose transport is not built yet; ``screen`` (:class:`~.screen.ScreenExitance`,
        optional): the objects' exitance at the pixel centres they are seen at, read instead of asking the transports
        where it is known. Counts and tables of earlier transports are dropped."""
        self.transports, self.screen = list(transports), screen
        #: Transport queries since :meth:`attach` (the stats' ``exitance_lookups``).
        self.count = 0
        #: The mesh tables of :attr:`transports`, by object (:meth:`_hit_exitance`).
        self._tables = {}
        #: The last batch of camera rays and their first hits whose ``M`` came from a transport: ``(rays, lanes,
        #: M (K, 3))``, numpy but the rays (the ``exitance`` AOV reads them instead of asking again, :mod:`.aovs`).
        self.first_recorded = (None, np.zeros(0, dtype=np.int64), np.zeros((0, 3)))
        return self

    def on_screen(self, si, which, translucent, weight):
        """Where the screen table knows ``M`` on the ``translucent`` lanes: ``(known, weight M)`` (Eq. V1)."""
        if self.screen is None:
            return dr.zeros(mi.Bool, dr.width(si.p)), dr.zeros(mi.Color3f, dr.width(si.p))
        exitance, known = self.screen.lookup(si, which)
        known &= translucent
        return known, dr.select(known, weight * exitance, 0.0)

    def resolve(self, transports, deferred, tables=None):
        """The radiance of the hits ``deferred`` (as :meth:`.path_tracer.PathTracer.incident` returned them) now
        that ``transports`` exist: ``(tags, values (K, 3))``, each hit's ``weight (1/pi) F_t M`` (paper Eq. 7) with its
        tag, hits of objects whose transport is still ``None`` left out. ``tables`` (a dict, filled here) holds the
        mesh tables of these ``transports`` for the next call on the same ones."""
        tables = {} if tables is None else tables
        tags, values = [np.zeros(0, dtype=np.int64)], [np.zeros((0, 3))]
        for k, tag, points, normals, faces, weight in deferred:
            if transports[k] is None:
                continue
            tags.append(tag)
            values.append(weight * self._hit_exitance(k, transports[k], points, normals, faces, tables))
        return np.concatenate(tags), np.concatenate(values)

    def exitance(self, k, points, normals):
        """Object ``k``'s ``M`` (K, 3) at ``points`` (mm) with outward ``normals``, from its transport (numpy)."""
        return self._exitance(self.transports[k], points, normals)

    def _hit_exitance(self, k, transport, points, normals, faces, tables):
        """Object ``k``'s ``M`` (K, 3) at path hits ``points`` (mm) with outward ``normals`` on its shape's ``faces``:
        from its mesh table of ``transport`` (:class:`~.mesh_exitance.MeshExitance`, Eq. V2 where the mesh resolves
        ``M``; kept in ``tables[k]``, None where the object can have none) when it can have one, else
        ``transport``'s."""
        if k not in tables:
            tables[k] = MeshExitance(self.objects[k], lambda p, n: self._exitance(transport, p, n),
                                     self.unit_mm) if usable(self.objects[k]) else None
        if tables[k] is None:
            return self._exitance(transport, points, normals)
        out = tables[k](faces, points, normals)
        if self.stop is not None and self.stop():  # the table may hold zeros where it was not asked: not kept
            tables.pop(k)
        return out

    def _exitance(self, transport, points, normals):
        """``transport``'s ``M`` at ``points`` (mm; (K, 3) numpy), asked in chunks of its ``query_batch``; chunks
        left when :attr:`stop` says so stay 0."""
        out = np.zeros((len(points), 3))
        for chunk in np.array_split(np.arange(len(points)), max(1, -(-len(points) // transport.query_batch))):
            if len(chunk) == 0 or (self.stop is not None and self.stop()):
                continue
            out[chunk] = transport.exitance(points[chunk], normals[chunk])
            self.count += len(chunk)
        return out

    def add_recorded(self, total, hits, incident=None, camera=None):
        """Adds to ``total`` the ``weight M`` of the hits a kernel recorded (:class:`HitRecords`) from each object's
        transport (numpy, positions in mm, outward normals for the transports that use them); hits on an object
        without a transport go to ``incident``'s deferred hits (``(deferred, tags, weight)`` of
        :meth:`.path_tracer.PathTracer.incident`) with their lane's tag and weight. Where the paths are ``camera``
        rays, the lanes and ``M`` (numpy) of the hits that were a ray's first are kept in :attr:`first_recorded`."""
        count = hits.count
        if count == 0:
            if camera is not None:
                self.first_recorded = (camera, np.zeros(0, dtype=np.int64), np.zeros((0, 3)))
            return
        written = dr.arange(mi.UInt32, count)
        owner, points, normals, beta, lanes, first, faces = (dr.gather(type(r), r, written).numpy().T
                                                             for r in hits.records)
        # The loop's threads record in any order; a path records its own hits in order: sorted by lane, the
        # transports are asked the same points in the same order whatever the threads (and neighbouring pixels' hits
        # together).
        order = np.argsort(lanes, kind="stable")
        owner, lanes, first, faces = owner[order], lanes[order], first[order], faces[order]
        points = points.reshape(-1, 3)[order].astype(np.float64) * self.unit_mm
        normals = normals.reshape(-1, 3)[order].astype(np.float64)
        beta = beta.reshape(-1, 3)[order].astype(np.float64)
        exitance = np.zeros((count, 3))
        for k, (obj, transport) in enumerate(zip(self.objects, self.transports)):
            mine = np.flatnonzero(owner == k)
            if len(mine) == 0:
                continue
            if transport is None:
                deferred, tags, weight = incident
                tag = lanes[mine]
                deferred.append((k, tags[tag], points[mine], normals[mine] * obj.orientation, faces[mine],
                                 beta[mine] * weight[tag]))
                continue
            exitance[mine] = self._hit_exitance(k, transport, points[mine], normals[mine] * obj.orientation,
                                                faces[mine], self._tables)
        # A lane's hits summed here, in their order, then one add per lane: a scatter-add of each hit would add a
        # lane's hits in the order the threads run, and the image would change in its last bits from run to run.
        lane, start = np.unique(lanes, return_index=True)
        summed = np.add.reduceat(beta * exitance, start, axis=0)
        dr.scatter_add(total, _color(summed), mi.UInt32(lane.astype(np.uint32)))
        if camera is not None:
            self.first_recorded = (camera, lanes[first].astype(np.int64), exitance[first])
