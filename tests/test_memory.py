"""``heatparam.memory``: large allocations are checked against the available memory before they are made."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from heatparam import memory
from heatparam.errors import ResourceError


def test_require_passes_up_to_the_safety_fraction_and_refuses_beyond(monkeypatch):
    avail = 10 * 2**30
    monkeypatch.setattr(memory, "available_bytes", lambda: avail)
    memory.require(memory.SAFETY_FRACTION * avail, "an array at the limit", "nothing to do")
    with pytest.raises(ResourceError):
        memory.require(1.01 * memory.SAFETY_FRACTION * avail, "an array just beyond it", "nothing to do")


def test_require_refuses_in_one_line_with_sizes_and_advice(monkeypatch):
    monkeypatch.setattr(memory, "available_bytes", lambda: 2**30)
    with pytest.raises(ResourceError) as e:
        memory.require(2 * 2**30, "an n x n matrix", "use geodesics='landmarks'")
    msg = str(e.value)
    assert "2.0 GiB" in msg and "1.0 GiB" in msg and "landmarks" in msg and "\n" not in msg


def test_available_bytes_is_the_systems_available_memory(monkeypatch):
    import psutil

    monkeypatch.setattr(psutil, "virtual_memory", lambda: SimpleNamespace(available=123_456_789.0, total=2**40))
    assert memory.available_bytes() == 123_456_789


def test_peak_rss_is_in_bytes_and_covers_what_is_resident_now():
    import psutil

    block = np.ones(32 * 2**20 // 8)  # 32 MiB, touched: resident
    rss = psutil.Process().memory_info().rss
    peak = memory.peak_rss_bytes()
    # bytes, not the kilobytes getrusage reports on Linux (the kernel's high-water mark may lag the RSS a little)
    assert 0.5 * rss <= peak < 1024 * rss
    assert block.sum() == len(block)
