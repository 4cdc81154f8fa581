"""Morton (Z-order) codes: the bits of three cell indices interleaved, so that sorting by code walks space along a
curve on which every run of consecutive cells is a compact region (the surface samples' faces, the octree's samples).
"""

import numpy as np

#: Bits per axis (3 x 21 = 63 bits in a uint64).
MORTON_BITS = 21


def spread_bits(v):
    """Insert two zero bits between each of the low 21 bits of ``v`` (uint64): bit k moves to bit 3k."""
    v = v & np.uint64(0x1FFFFF)
    v = (v | (v << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    v = (v | (v << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    v = (v | (v << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    v = (v | (v << np.uint64(2))) & np.uint64(0x1249249249249249)
    return v


def interleave(cells):
    """The Morton codes (N,) uint64 of integer ``cells`` (N, 3) in ``[0, 2^21)``: x in the lowest bit of each triple.

    >>> int(interleave(np.array([[1, 1, 1]], dtype=np.uint64))[0])
    7
    """
    cells = np.asarray(cells, dtype=np.uint64)
    return spread_bits(cells[:, 0]) | (spread_bits(cells[:, 1]) << np.uint64(1)) | \
        (spread_bits(cells[:, 2]) << np.uint64(2))
