"""A render in parts: its samples per pixel, their shares and the seeds of its parts, the passes and the walk's
kernels, one home for the render's machinery (issue 59).

A render of ``spp`` samples per pixel is drawn in parts (the passes of ``passes``, :func:`render_passes`; the walk's
kernels of :data:`~.integrator.WALK_LANES` paths, :func:`.film.render`; ``convsss reference``'s passes of
``pass_spp``), each with its share of the samples (:func:`shares`) and its own seed (:func:`pass_seed`); their mean,
weighted by the shares, is the image (the film's parts add their filter weights too). Ctrl-C stops between parts.
"""

import hashlib
import time

import numpy as np


def as_seed(seed):
    """A seed as a Python int (Mitsuba hands a one-lane ``UInt32`` to a plugin's ``render``)."""
    return int(np.asarray(seed, dtype=np.uint64).reshape(-1)[0]) if not isinstance(seed, int) else seed


def pass_seed(seed, k):
    """The seed of part ``k`` of a render of ``seed``: ``seed`` itself for the first (one part renders as a render
    in one), then a 32-bit hash of both, so that parts draw independent samples and camera rays."""
    if k == 0:
        return seed
    return int.from_bytes(hashlib.blake2b(f"{seed}:{k}".encode(), digest_size=4).digest(), "little")


def samples_per_pixel(spp, sensor):
    """The samples per pixel a render takes: ``spp`` where given (> 0), else the sensor's sampler's."""
    return int(spp) if spp else int(sensor.sampler().sample_count())


def shares(spp, parts=None, most=None):
    """``spp`` split into ``parts`` shares that differ by at most one, or into shares of at most ``most``, the last
    one the rest."""
    if parts is not None:
        parts = max(1, min(int(parts), int(spp)))
        return [spp // parts + (k < spp % parts) for k in range(parts)]
    return [min(int(most), spp - done) for done in range(0, spp, int(most))]


def render_passes(session, scene, sensor, seed, spp, shade):
    """A render of ``session`` (a :class:`~.session.RenderSession`) in ``passes`` passes: each prepares fresh
    samples (its share of ``sample_density`` and ``profile_samples``, seed :func:`pass_seed`) and shades its share of
    ``spp`` with ``shade(spp, seed)`` (the plugin's Mitsuba loop); returns the passes' mean, weighted by their camera
    samples. Stops early at ``time_limit``. The session's ``stats`` sum the stages' seconds and list the passes; its
    ``objects`` are the last pass's."""
    p = session.params
    parts = shares(spp, parts=p.passes)
    count = len(parts)
    share_params = p.replace(sample_density=p.sample_density / count, profile_samples=p.profile_samples / count)
    start, seconds, done, image, survey = time.perf_counter(), {}, [], None, None
    try:
        session.params = share_params
        for k, share in enumerate(parts):
            session.announce(f"pass {k + 1}/{count}")
            pass_start, own_seed = time.perf_counter(), pass_seed(seed, k)
            session.prepare(scene, sensor, own_seed, survey)
            survey = session.prepared.survey
            shaded = shade(share, own_seed)
            image = shaded * share if image is None else image + shaded * share
            for name, t in session.stats["seconds"].items():
                seconds[name] = seconds.get(name, 0.0) + t
            done.append({"seed": own_seed, "spp": share, "samples": session.stats["samples"],
                         "seconds": time.perf_counter() - pass_start})
            elapsed = time.perf_counter() - start
            if p.time_limit and k + 1 < count and elapsed * (k + 2) / (k + 1) > p.time_limit:
                break
    finally:
        session.params = p
        # Mitsuba's render sets the sampler's count to each pass's share: leave it as a one-pass render would
        sensor.sampler().set_sample_count(spp)
    spp_done = sum(d["spp"] for d in done)
    session.stats.update(parameters=p.to_dict(), seconds=seconds, passes=done,
                      samples=sum(d["samples"] for d in done))
    session.stats["film"]["spp"] = spp_done
    return image * (1.0 / spp_done)
