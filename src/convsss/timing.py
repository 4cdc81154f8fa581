"""Per-stage wall-clock timings, kept next to results so stats and benchmarks report the same numbers."""

import time
from contextlib import contextmanager


class StageTimer(dict):
    """A dict ``stage -> seconds``; ``with timer("fft"): ...`` adds the block's wall time to ``timer["fft"]``.

    ``sync``, if given, is called at the end of each block before the clock is read: work a block launched
    asynchronously (Dr.Jit's kernels, ``drjit.sync_thread``) is then counted in that block, not in a later one.
    """

    def __init__(self, sync=None):
        super().__init__()
        self.sync = sync

    @contextmanager
    def __call__(self, stage):
        start = time.perf_counter()
        try:
            yield
        finally:
            if self.sync is not None:
                self.sync()
            self[stage] = self.get(stage, 0.0) + time.perf_counter() - start
