"""The kernel spectra cache (convsss.transport.kernels.KernelCache): bounded in count and in bytes, so that a
long-lived process does not keep a dense medium's gigabytes of spectra (issue 30, defect 13)."""

import numpy as np

from convsss.transport.kernels import KernelCache


def test_the_cache_keeps_the_newest_entries_within_its_bytes():
    cache = KernelCache(size=3, max_bytes=1000)
    small = [np.zeros(50, dtype=np.float32) for _ in range(4)]  # 200 bytes each
    for k, value in enumerate(small):
        cache.put(k, value)
    assert cache.get(0) is None and all(cache.get(k) is small[k] for k in (1, 2, 3))  # the newest three
    cache.put("pair", (np.zeros(100, dtype=np.float32), np.zeros(50, dtype=np.float32)))  # 600 bytes
    assert cache.nbytes <= 1000 and cache.get("pair") is not None and cache.get(1) is None
    cache.put("huge", np.zeros(1000, dtype=np.float32))  # over the bound alone: not kept, nothing evicted for it
    assert cache.get("huge") is None and cache.get("pair") is not None
