"""The simulator's heap setting (radar/heap.py)."""

import platform

from radar2shape.radar.heap import keep_freed_blocks


def test_keep_freed_blocks_is_accepted_by_glibc_and_idempotent():
    first = keep_freed_blocks()
    assert keep_freed_blocks() is first  # set once per process
    if platform.libc_ver()[0] == "glibc":
        assert first is True
    else:
        assert first is False
