"""The half-space's response on the grid, solved along depth (Thomas's algorithm): what the grid's sources and reads
are calibrated by (:mod:`convsss.transport.volume`)."""

import math

import numpy as np

#: Where the boundary falls within a cell, and where the source falls laterally, for the average of
#: :func:`half_space_response` (fractions of a cell).
OFFSETS = (0.125, 0.375, 0.625, 0.875)


#: Read-back pairs per offset in :func:`half_space_response`.
READS = 60_000


def _thomas(lower, diagonal, rhs):
    """Solve tridiagonal systems, one per column: constant ``lower`` (= upper) off-diagonal, ``diagonal`` (n, M)
    and ``rhs`` (n, M, R) for R right-hand sides."""
    n = len(diagonal)
    cp = np.empty_like(diagonal)
    dp = np.empty_like(rhs)
    beta = diagonal[0]
    cp[0] = lower / beta
    dp[0] = rhs[0] / beta[:, None]
    for k in range(1, n):
        beta = diagonal[k] - lower * cp[k - 1]
        cp[k] = lower / beta
        dp[k] = (rhs[k] - lower * dp[k - 1]) / beta[:, None]
    x = np.empty_like(rhs)
    x[-1] = dp[-1]
    for k in range(n - 2, -1, -1):
        x[k] = dp[k] - cp[k][:, None] * x[k + 1]
    return x


def _depth_weights(s, delta, h, moment):
    """Linear weights over the depth nodes ``floor(s)``, ``floor(s) + 1`` (node ``k`` at ``(k + delta) h`` below the
    extrapolated boundary), kept where the node index is >= 0 and scaled to the ``moment`` (:func:`moment_weights`):
    (nodes (2,), weights (2,))."""
    k = math.floor(s)
    nodes = np.array([k, k + 1])
    w = np.where(nodes >= 0, np.array([k + 1 - s, s - k]), 0.0)
    nodes = np.maximum(nodes, 0)
    return nodes, w * moment / np.sum(w * (nodes + delta) * h)


def half_space_response(diffusion, sigma_a, source_depth, read_depths, read_weights, h, reach, seed=0):
    """``T(r)`` of Eq. D2 for one channel: the grid solver's slope of Eq. D4 (``sum_j w_j u(d_j)``, the reads at
    ``read_depths`` with ``read_weights``) under a surface point at distance ``r`` from a unit flux's entry point on
    a flat half-space, averaged over :data:`OFFSETS` of the boundary within a cell and of the source laterally, and
    over directions. Returns (r (n,), T (n,)), non-increasing.

    The grid is periodic laterally (``N`` nodes, twice the reach) and Dirichlet below the reach, so each lateral
    Fourier mode is a tridiagonal system in depth: the same rows as the object's matrix for a boundary parallel to
    a grid plane, solved exactly."""
    n_lat = 2 * int(math.ceil(reach / h)) + 8
    n_z = int(math.ceil(max(reach + max(read_depths), source_depth + 2.0 * h) / h)) + 4  # the source within it
    m = np.fft.fftfreq(n_lat)
    lam = (4.0 / h**2) * (np.sin(np.pi * m)[:, None] ** 2 + np.sin(np.pi * m)[None, :] ** 2)
    link = diffusion / h**2
    rng = np.random.default_rng(seed)
    edges = np.arange(0.0, reach + 0.25 * h, 0.25 * h)
    total, count = np.zeros(len(edges) - 1), np.zeros(len(edges) - 1)
    for delta in OFFSETS:
        # node k at (k + delta) h inside the extrapolated boundary (the source at Eq. D5's depth, the reads at Eq. D4's)
        diagonal = np.broadcast_to(2.0 * link + sigma_a + diffusion * lam.ravel(), (n_z, lam.size)).copy()
        diagonal[0] += link * (1.0 / delta - 1.0)  # the link to the boundary, a fraction delta of a cell away
        src_nodes, src_w = _depth_weights(source_depth / h - delta, delta, h, source_depth)
        reads = [_depth_weights(d / h - delta, delta, h, d) for d in read_depths]
        rhs = np.zeros((n_z, lam.size, 2))
        rhs[src_nodes[0], :, 0] = 1.0 / h**3
        rhs[src_nodes[1], :, 1] = 1.0 / h**3
        modes = _thomas(-link, diagonal, rhs)  # (n_z, modes, 2)
        fields = np.fft.ifft2(modes.reshape(n_z, n_lat, n_lat, 2), axes=(1, 2)).real  # unit source at (0, 0)
        surface = sum(weight * src_w[a] * read_w[b] * fields[read_nodes[b], :, :, a]
                      for weight, (read_nodes, read_w) in zip(read_weights, reads) for a in (0, 1) for b in (0, 1))
        r = rng.uniform(0.0, reach, READS)
        phi = rng.uniform(0.0, 2.0 * np.pi, READS)
        source = rng.uniform(0.0, 1.0, (READS, 2))  # the entry point within its cell
        read = source + (r / h)[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        value = np.zeros(READS)
        base = np.floor(read).astype(np.int64)
        frac = read - base
        for sx in (0, 1):
            for sy in (0, 1):
                ws = (source[:, 0] if sx else 1 - source[:, 0]) * (source[:, 1] if sy else 1 - source[:, 1])
                for rx in (0, 1):
                    for ry in (0, 1):
                        wr = (frac[:, 0] if rx else 1 - frac[:, 0]) * (frac[:, 1] if ry else 1 - frac[:, 1])
                        ix, iy = (base[:, 0] + rx - sx) % n_lat, (base[:, 1] + ry - sy) % n_lat
                        value += ws * wr * surface[ix, iy]
        which = np.minimum(np.searchsorted(edges, r, side="right") - 1, len(total) - 1)
        total += np.bincount(which, value, len(total))
        count += np.bincount(which, minlength=len(total))
    centre = 0.5 * (edges[1:] + edges[:-1])
    mean = np.minimum.accumulate(np.maximum(total / np.maximum(count, 1), 0.0))
    return np.concatenate([[0.0], centre]), np.concatenate([[mean[0]], mean])
