"""The memory guard (convsss.memory): what is available, within a process's budget, and refusals before allocating."""

import pytest

from convsss import memory
from convsss.errors import ConvsssError


@pytest.fixture
def budget():
    yield memory.set_budget
    memory.set_budget(None)


def test_a_budget_bounds_what_is_available_by_what_the_process_holds(budget):
    free = memory.available_memory()
    held = memory.resident_memory()
    assert free > 0 and held > 0
    budget(held + 2**20)  # one MiB more than it holds now
    assert memory.available_memory() <= 2**20
    with pytest.raises(ConvsssError, match="need about 0.1 GiB, more than the 0.0 GiB allowed: smaller"):
        memory.check_memory(100 * 2**20, "the test's arrays", "smaller")
    budget(held // 2)  # already over it: nothing is available
    assert memory.available_memory() == 0
    budget(None)
    assert memory.available_memory() > 2**20


def test_check_memory_passes_what_fits():
    memory.check_memory(1024, "a kilobyte", "none needed")
    memory.check_memory(10, "ten bytes", "none", limit=10)
    with pytest.raises(ConvsssError, match="ten bytes need about"):
        memory.check_memory(11, "ten bytes", "none", limit=10)


def test_a_process_memory_limit_bounds_what_is_available():
    """Under ``ulimit -v`` (RLIMIT_AS) what is available is at most the address space left, not the machine's RAM
    (a fresh process: the limit cannot be raised again)."""
    import subprocess
    import sys

    code = ("import resource; from convsss import memory; "
            "size = int(open('/proc/self/statm').read().split()[0]) * 4096; "
            "resource.setrlimit(resource.RLIMIT_AS, (size + 2**30, resource.RLIM_INFINITY)); "
            "print(memory.available_memory())")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert 0 < int(done.stdout) <= 2**30 + 2**20


def test_a_cgroup_limit_bounds_what_is_available(monkeypatch, tmp_path):
    """A container's memory limit (cgroup v2's ``memory.max`` less ``memory.current``) bounds it; ``max`` is none."""
    limit, usage = tmp_path / "memory.max", tmp_path / "memory.current"
    monkeypatch.setattr(memory, "_CGROUP_FILES", ((str(limit), str(usage)),))
    limit.write_text(f"{3 * 2**20}\n")
    usage.write_text(f"{2**20}\n")
    assert memory.available_memory() == 2 * 2**20
    limit.write_text("max\n")
    assert memory.available_memory() > 2 * 2**20
