"""Memory refused before it is allocated: one guard for every large allocation (grids, samples, wavefronts)."""

from .errors import ConvsssError

#: The share of the available memory a single allocation may take.
USABLE_FRACTION = 0.75


def available_memory():
    """Bytes of memory available now (``MemAvailable``), or None where that cannot be read."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


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
