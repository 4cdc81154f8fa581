"""Memory refused before it is allocated: one guard for every large allocation (grids, samples, wavefronts)."""

from .errors import ConvsssError

#: The share of the available memory a single allocation may take.
USABLE_FRACTION = 0.75


#: Bytes this process may hold in all, or None (the machine's memory alone): :func:`set_budget`.
_budget = None


def set_budget(nbytes):
    """Hold this process to ``nbytes`` in all (None: no budget of its own), as a batch worker is held to its share
    of the machine (:func:`convsss.batch.runner.run_job`): what is available is then at most the budget less what
    the process already holds."""
    global _budget
    _budget = None if nbytes is None else int(nbytes)


def resident_memory():
    """Bytes this process holds now (its resident set, ``/proc/self/statm``), or None where that cannot be read."""
    import os

    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return None


def available_memory():
    """Bytes of memory available now (``MemAvailable``, within the process's :func:`set_budget`), or None where
    that cannot be read."""
    available = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    available = int(line.split()[1]) * 1024
                    break
    except OSError:
        pass
    held = resident_memory() if _budget is not None else None
    if held is not None:
        left = max(_budget - held, 0)
        available = left if available is None else min(available, left)
    return available


def check_memory(needed, what, advice, limit=None):
    """A one-line :class:`ConvsssError` when ``needed`` bytes exceed ``limit`` (default: 75 % of what is available):
    "``what`` need about X GiB, more than the Y GiB available: ``advice``"."""
    if limit is None:
        available = available_memory()
        if available is None:
            return
        limit = USABLE_FRACTION * available
    if needed > limit:
        raise ConvsssError(f"{what} need about {needed / 2**30:.1f} GiB, more than the {limit / 2**30:.1f} GiB "
                           f"allowed: {advice}")
