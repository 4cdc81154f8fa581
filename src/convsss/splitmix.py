"""splitmix64 streams for the compiled Monte Carlo loops (numba): each walk's numbers from its own 64-bit state, so
that a table does not depend on the thread count.

:func:`uniform` steps a state and gives a number uniform in (0, 1) (never 0 nor 1: ``-log(u)`` and ``-log(1 - u)``
are finite); :func:`isotropic` a direction uniform on the sphere; :func:`mix` is the generator's finalizer, a 64-bit
hash to start a stream from a seed and a walk's index.
"""

import math

import numpy as np

from .jit import njit


@njit(inline="always", cache=True)
def mix(z):
    """splitmix64's finalizer: a 64-bit hash."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(inline="always", cache=True)
def uniform(state):
    """splitmix64: returns (new state, uniform in (0, 1))."""
    state = state + np.uint64(0x9E3779B97F4A7C15)
    return state, (np.float64(mix(state) >> np.uint64(11)) + 0.5) * (1.0 / 9007199254740992.0)


@njit(inline="always", cache=True)
def isotropic(state):
    """(new state, x, y, z): a direction uniform on the sphere, its cosine to z from the first number, its azimuth
    from the second."""
    state, u = uniform(state)
    state, v = uniform(state)
    z = 1.0 - 2.0 * u
    r = math.sqrt(max(1.0 - z * z, 0.0))
    return state, r * math.cos(2.0 * math.pi * v), r * math.sin(2.0 * math.pi * v), z
