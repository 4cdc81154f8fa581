"""Per-stage wall-clock timings, kept next to results so stats and benchmarks report the same numbers."""

import time
from contextlib import contextmanager


class StageTimer(dict):
    """A dict ``stage -> seconds``; ``with timer("fft"): ...`` adds the block's wall time to ``timer["fft"]``."""

    @contextmanager
    def __call__(self, stage):
        start = time.perf_counter()
        try:
            yield
        finally:
            self[stage] = self.get(stage, 0.0) + time.perf_counter() - start
