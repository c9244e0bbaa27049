"""The Examples sections of the public API run as written (doctest)."""

from __future__ import annotations

import doctest
import importlib

import pytest

PUBLIC = ("heatparam.pipeline", "heatparam.mesh.validate", "heatparam.refine", "heatparam.heat")


@pytest.mark.parametrize("name", PUBLIC)
def test_examples_run(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0, result
