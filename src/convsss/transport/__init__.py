"""Transports: from irradiance samples to radiant exitance ``M`` anywhere (see :mod:`convsss.transport.base`).

Each transport is a plug-in: a :class:`~convsss.transport.base.Transport` subclass in its own module that declares
its parameters and registers itself (``register_transport`` on the module's last line). Importing this package
imports them all, so :data:`TRANSPORTS` holds every one:

- ``exact``: the direct sum over all samples (reference, small cases);
- ``convolution``: the paper's layered FFT convolutions (§4–5);
- ``hierarchical``: Jensen & Buhler 2002's octree, the paper's comparison method (§6);
- ``multiscale``: the profile split in a near field (direct sum over clustered samples) and a far field (3-D FFT);
- ``volume``: Eq. 1 corrected by the diffusion equation solved on the object's volume (light through the body).
"""

from ..errors import ConvsssError
from . import convolution, exact, hierarchical, multiscale, volume  # noqa: F401  (each registers its transport)
from .base import TRANSPORTS, Transport, register_transport
from .convolution import ConvolutionTransport
from .exact import ExactTransport
from .hierarchical import HierarchicalTransport
from .multiscale import MultiscaleTransport
from .volume import VolumeTransport


def clear_caches():
    """Forget every cached kernel spectrum and plane-correction table (for cold timings, or to free memory)."""
    from .correction import RESPONSES
    from .kernels import CACHE
    from .multiscale import SPECTRA
    from .volume import RESPONSES as VOLUME_RESPONSES

    CACHE.clear()
    RESPONSES.clear()
    SPECTRA.clear()
    VOLUME_RESPONSES.clear()


def make_transport(kind, samples, profile, frame=None, material=None, **params):
    """The transport called ``kind``: ``TRANSPORTS[kind](samples, profile, frame, material, **params)``.

    ``frame`` is the camera's :class:`~convsss.samples.ViewFrame` (the convolution needs it; the others accept
    ``None``); ``params`` are the transport's declared parameters (``TRANSPORTS[kind].parameters``).
    """
    if kind not in TRANSPORTS:
        raise ConvsssError(f"unknown transport {kind!r}: choose one of {', '.join(sorted(TRANSPORTS))}")
    return TRANSPORTS[kind](samples, profile, frame, material, **params)


__all__ = ["ConvolutionTransport", "ExactTransport", "HierarchicalTransport", "MultiscaleTransport", "TRANSPORTS",
           "Transport", "VolumeTransport", "clear_caches", "make_transport", "register_transport"]
