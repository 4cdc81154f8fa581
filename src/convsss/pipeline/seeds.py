"""How a render draws: its samples per pixel and the seeds of its parts, one home for both (issue 59).

A render of ``spp`` samples per pixel is drawn in parts (the passes of ``passes``, the walk's kernels of
:data:`~.integrator.WALK_LANES` paths, ``convsss reference``'s passes of ``pass_spp``), each with its share of the
samples (:func:`shares`) and its own seed (:func:`pass_seed`); their mean, weighted by the shares, is the image.
"""

import hashlib

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
