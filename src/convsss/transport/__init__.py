"""Transports: from irradiance samples to radiant exitance ``M`` anywhere (see :mod:`convsss.transport.base`).

- ``exact``: the direct sum over all samples (reference, small cases);
- ``convolution``: the paper's layered FFT convolutions (§4–5).
"""

from ..errors import ConvsssError
from .base import Transport, total_flux
from .exact import ExactTransport

TRANSPORTS = {"exact": ExactTransport}


def make_transport(kind, samples, profile, **params):
    """Build the transport called ``kind`` from ``samples`` and ``profile`` with its own keyword ``params``."""
    if kind not in TRANSPORTS:
        raise ConvsssError(f"unknown transport {kind!r}: choose one of {', '.join(sorted(TRANSPORTS))}")
    return TRANSPORTS[kind](samples, profile, **params)


__all__ = ["ExactTransport", "TRANSPORTS", "Transport", "make_transport", "total_flux"]
