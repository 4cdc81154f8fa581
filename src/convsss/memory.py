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


def _statm(field):
    """Field ``field`` of ``/proc/self/statm`` in bytes (0: the process's size, 1: its resident set), or None where
    that cannot be read."""
    import os

    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[field]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return None


def resident_memory():
    """Bytes this process holds now (its resident set, ``/proc/self/statm``), or None where that cannot be read."""
    return _statm(1)


def _address_space_left():
    """Bytes of address space this process may still map under its ``RLIMIT_AS`` (``ulimit -v``; its size now from
    ``/proc/self/statm``), or None where it has no such limit."""
    import resource

    limit = resource.getrlimit(resource.RLIMIT_AS)[0]
    if limit == resource.RLIM_INFINITY:
        return None
    size = _statm(0)
    return limit if size is None else max(limit - size, 0)


#: Where a control group's limit and use are read: cgroup v2 (``memory.max``, at the root a container sees) and v1.
_CGROUP_FILES = (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                 ("/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes"))


def _cgroup_left():
    """Bytes the process's control group (a container's or a systemd slice's memory limit) may still take, or None
    where it has no limit or none can be read."""
    for limit_file, usage_file in _CGROUP_FILES:
        try:
            with open(limit_file) as f:
                limit = f.read().strip()
            if limit == "max" or int(limit) >= 2**60:  # v1 writes "no limit" as a number near 2^63
                return None
            with open(usage_file) as f:
                return max(int(limit) - int(f.read()), 0)
        except (OSError, ValueError):
            continue
    return None


def available_memory():
    """Bytes of memory available now: the machine's ``MemAvailable``, within the process's ``RLIMIT_AS``, its
    control group's limit and its :func:`set_budget`; None where none of them can be read."""
    found = []
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    found.append(int(line.split()[1]) * 1024)
                    break
    except OSError:
        pass
    found += [left for left in (_address_space_left(), _cgroup_left()) if left is not None]
    held = resident_memory() if _budget is not None else None
    if held is not None:
        found.append(max(_budget - held, 0))
    return min(found) if found else None


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
