"""Open-addressing hash tables of int64 keys for numba loops that group, count or look up integer keys (cubes,
voxels, corners): a table is two arrays of a power-of-two length, ``keys`` and ``values``, a value of -1 marking an
empty slot. Linear probing from the key's multiplicative hash; a table kept at most half full stays fast.

>>> keys, values = empty(capacity(3))
>>> for key in (7, 42, 7):
...     slot = probe(keys, values, key)
...     values[slot] = values[slot] + 1 if values[slot] >= 0 else 1
...     keys[slot] = key
>>> int(values[probe(keys, values, 7)]), int(values[probe(keys, values, 42)]), int(values[probe(keys, values, 5)])
(2, 1, -1)
"""

import numpy as np

from .jit import njit

#: The hash's multiplier (odd, 64-bit): a key's home slot is the low bits of ``key * MULTIPLIER``.
MULTIPLIER = 0x2545F4914F6CDD1D


@njit(cache=True)
def capacity(count):
    """The table length for ``count`` keys: the smallest power of two, at least 16, that is twice ``count``."""
    size = 16
    while size < 2 * count:
        size *= 2
    return size


@njit(cache=True)
def empty(size):
    """An empty table of ``size`` slots (a power of two): ``(keys, values)``, every value -1."""
    return np.zeros(size, dtype=np.int64), np.full(size, -1, dtype=np.int64)


@njit(inline="always")
def probe(keys, values, key):
    """The slot holding ``key``, or the empty one (value -1) where it would go; the table must have an empty slot."""
    mask = keys.shape[0] - 1
    slot = (key * MULTIPLIER) & mask
    while values[slot] >= 0 and keys[slot] != key:
        slot = (slot + 1) & mask
    return slot


@njit(cache=True)
def grown(keys, values, size):
    """The table moved into one of ``size`` slots (a power of two, larger than its entries)."""
    new_keys, new_values = empty(size)
    for s in range(keys.shape[0]):
        if values[s] >= 0:
            slot = probe(new_keys, new_values, keys[s])
            new_keys[slot], new_values[slot] = keys[s], values[s]
    return new_keys, new_values
