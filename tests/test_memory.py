"""``heatparam.memory``: large allocations are checked against the available memory before they are made."""

from __future__ import annotations

import pytest

from heatparam import memory
from heatparam.errors import ResourceError


def test_require_passes_within_the_safety_fraction(monkeypatch):
    monkeypatch.setattr(memory, "available_bytes", lambda: 10 * 2**30)
    memory.require(0.5 * memory.SAFETY_FRACTION * 10 * 2**30, "a small array", "nothing to do")


def test_require_refuses_in_one_line_with_sizes_and_advice(monkeypatch):
    monkeypatch.setattr(memory, "available_bytes", lambda: 2**30)
    with pytest.raises(ResourceError) as e:
        memory.require(2 * 2**30, "an n x n matrix", "use geodesics='landmarks'")
    msg = str(e.value)
    assert "2.0 GiB" in msg and "1.0 GiB" in msg and "landmarks" in msg and "\n" not in msg


def test_available_and_peak_are_positive():
    assert memory.available_bytes() > 0 and memory.peak_rss_bytes() > 0
