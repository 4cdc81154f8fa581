"""StageTimer: per-stage sums, and the sync that bills asynchronous work to the stage that launched it."""

import time

from convsss.timing import StageTimer


def test_blocks_of_a_stage_add_up():
    timer = StageTimer()
    for _ in range(2):
        with timer("a"):
            time.sleep(0.01)
    assert 0.02 <= timer["a"] < 1.0
    assert list(timer) == ["a"]


def test_sync_runs_before_the_clock_is_read():
    calls = []

    def sync():
        calls.append("sync")
        time.sleep(0.05)  # the work a block launched, finishing

    timer = StageTimer(sync=sync)
    with timer("a"):
        calls.append("block")
    assert calls == ["block", "sync"]
    assert timer["a"] >= 0.05
    assert dict(timer) == {"a": timer["a"]}
