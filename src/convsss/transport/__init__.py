"""Transports: from irradiance samples to radiant exitance ``M`` anywhere (see :mod:`convsss.transport.base`).

- ``exact``: the direct sum over all samples (reference, small cases);
- ``convolution``: the paper's layered FFT convolutions (§4–5);
- ``hierarchical``: Jensen & Buhler 2002's octree, the paper's comparison method (§6).
"""

from ..errors import ConvsssError
from .base import Transport, total_flux
from .convolution import ConvolutionTransport
from .exact import ExactTransport
from .hierarchical import HierarchicalTransport

TRANSPORTS = {"convolution": ConvolutionTransport, "exact": ExactTransport, "hierarchical": HierarchicalTransport}


def make_transport(kind, samples, profile, frame=None, **params):
    """Build the transport called ``kind`` from ``samples`` and ``profile`` with its own keyword ``params``.

    ``frame`` (the camera's :class:`~convsss.samples.ViewFrame`) goes to the transports that use one.
    """
    if kind not in TRANSPORTS:
        raise ConvsssError(f"unknown transport {kind!r}: choose one of {', '.join(sorted(TRANSPORTS))}")
    if kind == "convolution":
        params["frame"] = frame
    return TRANSPORTS[kind](samples, profile, **params)


__all__ = ["ConvolutionTransport", "ExactTransport", "HierarchicalTransport", "TRANSPORTS", "Transport",
           "make_transport", "total_flux"]
