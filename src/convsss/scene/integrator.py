"""The ``convsss`` Mitsuba integrator: scene -> irradiance samples -> transport -> shading (DESIGN.md data flow).

``render()`` does, for one sensor:

1. find the translucent objects (:mod:`.objects`);
2. per object, sample its whole surface, ``N = sample_density * A / h^2`` points for a layer cell ``h`` (the pixel
   footprint at the object's depth divided by ``downsample``), so every cell column gets several samples, and
   compute their irradiance (paper Eq. 2, :mod:`.irradiance`);
3. build each object's transport (paper §4–5 for ``convolution``) in the camera's frame;
4. shade the camera rays (:mod:`.shading`) through Mitsuba's own render loop, so the film, its reconstruction
   filter, crop window, sampler and sample count behave as for any Mitsuba integrator.

Per-stage seconds and everything a user needs to judge the run are in :attr:`ConvsssIntegrator.stats`.
"""

import inspect
import math

import drjit as dr
import numpy as np

from ..backend import load_mitsuba, ordered_kernels
from ..errors import ConvsssError
from ..samples import IrradianceSamples, ViewFrame
from ..timing import StageTimer
from ..transport import TRANSPORTS, make_transport
from ..transport.convolution import available_memory
from .irradiance import sample_surface, surface_irradiance
from .objects import find_translucent_objects
from .params import RenderParams
from .shading import Shader

mi = load_mitsuba()

#: Bytes per path of one wavefront (ray, interaction, BSDF sample, throughput, lanes): measured order of magnitude.
BYTES_PER_PATH = 600
#: Bytes per surface sample while its irradiance is computed and the transport is built.
BYTES_PER_SAMPLE = 400


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


def _seed(seed):
    return int(np.asarray(seed, dtype=np.uint64).reshape(-1)[0]) if not isinstance(seed, int) else seed


class ConvsssIntegrator(mi.SamplingIntegrator):
    """Convolution-based subsurface scattering (Munoz et al. 2011) as a Mitsuba 3 integrator; see the module doc.

    Parameters (Mitsuba properties) are those of :class:`~convsss.scene.params.RenderParams`, plus Mitsuba's own
    ``samples_per_pass``.
    """

    def __init__(self, props):
        super().__init__(props)
        self.params = RenderParams.from_properties(props)
        self.samples_per_pass = int(props["samples_per_pass"]) if "samples_per_pass" in props else -1
        self.stats = {}
        #: Optional callable ``progress(stage)`` told when a stage starts (the command line's progress display).
        self.progress = None
        self._shader = None
        self._nested = False
        self._threads = 1

    def to_string(self):
        return f"ConvsssIntegrator[{', '.join(f'{k}={v!r}' for k, v in self.params.to_dict().items())}]"

    def aov_names(self):
        return []

    # --- stages -----------------------------------------------------------------------------------------------------
    def _stage(self, name):
        if self.progress is not None:
            self.progress(name)

    def prepare(self, scene, sensor, seed=0):
        """Stages 1–3 for ``sensor``: translucent objects, their irradiance samples and transports."""
        p = self.params
        timer = StageTimer()
        self._stage("samples")
        with timer("samples"):
            objects = find_translucent_objects(mi, scene, p.unit_mm, p.profile)
        frame = sensor_frame(sensor, p.unit_mm)
        transports, per_object = [], []
        for k, obj in enumerate(objects):
            centre = 0.5 * (obj.bbox_mm[0] + obj.bbox_mm[1])
            depth = float(frame.to_view(centre[None])[0, 2])
            if depth <= 0:
                raise ConvsssError(f"translucent shape {obj.name!r} is behind the camera (view depth {depth:.4g} mm)")
            cell_full = pixel_footprint(sensor, frame, depth, p.unit_mm)
            cell = cell_full / p.downsample
            count = max(64, math.ceil(p.sample_density * obj.area_mm2 / cell**2))
            self._check_memory(count * BYTES_PER_SAMPLE * max(1, min(p.irradiance_samples, 64) // 4),
                               f"{count} surface samples of {obj.name!r}",
                               "lower sample_density, or use downsample 0.5 or 0.25")
            self._stage("samples")
            with timer("samples"):
                position, normal, n = sample_surface(obj.shape, count, _seed(seed), obj.orientation, stream=k)
                position_mm = np.ascontiguousarray(dr.ravel(position).numpy().reshape(-1, 3), dtype=np.float64)
                position_mm *= p.unit_mm
                normal_np = dr.ravel(normal).numpy().reshape(-1, 3).astype(np.float64)
            self._stage("irradiance")
            with timer("irradiance"):
                irradiance = surface_irradiance(scene, position, normal, obj.eta, p.irradiance_samples,
                                                _seed(seed) + 7919 * k)
                samples = IrradianceSamples(position_mm, np.full(n, obj.area_mm2 / n), irradiance, normal_np)
            self._stage("transport")
            with timer("transport"):
                transport = make_transport(p.transport, samples, obj.profile, frame=frame,
                                           **self._transport_params(cell_full))
            transports.append(transport)
            per_object.append({**obj.summary(), "samples": n, "cell_size_mm": cell,
                               "pixel_footprint_mm": cell_full, "view_depth_mm": depth,
                               "flux": samples.flux.sum(axis=0).tolist()})
        self._shader = Shader(scene, objects, transports, p)
        self.stats = {"parameters": p.to_dict(), "seconds": dict(timer), "objects": per_object,
                      "samples": int(sum(o["samples"] for o in per_object))}
        return self._shader

    def _transport_params(self, cell_full):
        p = self.params
        candidates = {"layers": p.layers, "cell_size": cell_full, "downsample": p.downsample,
                      "threshold": p.threshold, "splat": p.splat, "correction": p.correction}
        accepted = inspect.signature(TRANSPORTS[p.transport]).parameters
        return {k: v for k, v in candidates.items() if k in accepted}

    @staticmethod
    def _check_memory(needed, what, advice):
        available = available_memory()
        if available is not None and needed > 0.75 * available:
            raise ConvsssError(f"{what} need about {needed / 2**30:.1f} GiB, more than the "
                               f"{0.75 * available / 2**30:.1f} GiB available: {advice}")

    # --- Mitsuba's interface ------------------------------------------------------------------------------------------
    def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
        if self._nested:  # Mitsuba's own loop, called from below: let it run
            return mi.SamplingIntegrator.render(self, scene, sensor, seed, spp, develop, evaluate)
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        film = sensor.film()
        size = film.crop_size()
        spp_used = spp if spp else sensor.sampler().sample_count()
        per_pass = min(spp_used, self.samples_per_pass) if self.samples_per_pass > 0 else spp_used
        self._check_memory(int(size[0]) * int(size[1]) * per_pass * BYTES_PER_PATH,
                           f"{size[0]}x{size[1]} pixels at {per_pass} samples per pass",
                           "set the integrator's samples_per_pass (e.g. 4) or render fewer spp")
        self.prepare(scene, sensor, seed)
        self._stage("shading")
        timer = StageTimer()
        self._nested = True
        try:
            # Mitsuba's film kernel scatter-adds each sample to every pixel its reconstruction filter covers: it runs
            # on one thread, in lane order, so the image is bit-identical whatever the thread count; the shading
            # (sample) runs on all threads.
            with timer("shading"), ordered_kernels() as self._threads:
                image = mi.SamplingIntegrator.render(self, scene, sensor, seed, spp, develop, evaluate)
                dr.eval(image)
        finally:
            self._nested = False
        self.stats["seconds"].update(timer)
        self.stats["film"] = {"size": [int(x) for x in film.size()], "crop_size": [int(x) for x in size],
                              "spp": int(spp_used)}
        self.stats["transports"] = [t.stats for t in self._shader.transports]
        self.stats["exitance_lookups"] = self._shader.lookups
        self._shader = None
        return image

    def sample(self, scene, sampler, ray, medium=None, active=True):
        if self._shader is None or self._shader.scene is not scene:
            # Called by another integrator's loop (e.g. Mitsuba's `aov`) without our render(): first sensor.
            self.prepare(scene, scene.sensors()[0], 0)
        if self._nested:  # all threads for the shading, then one again for Mitsuba's film kernel (see render)
            dr.set_thread_count(self._threads)
        radiance, valid = self._shader.shade(sampler, ray)
        if self._nested:
            dr.eval(radiance, valid)
            dr.set_thread_count(1)
        return radiance, valid, []


def register():
    """Register ``convsss`` with Mitsuba (``<integrator type="convsss">``); call before loading a scene."""
    mi.register_integrator("convsss", lambda props: ConvsssIntegrator(props))
    return mi
