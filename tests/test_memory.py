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
