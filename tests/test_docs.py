"""The Examples sections of the public API run as written (doctest); docs/options.md is the option table's."""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

from heatparam.options import GROUPS, OPTIONS, help_text, markdown_table, options_markdown

PUBLIC = ("heatparam.pipeline", "heatparam.mesh.validate", "heatparam.refine", "heatparam.heat")


@pytest.mark.parametrize("name", PUBLIC)
def test_examples_run(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0, result


ROOT = Path(__file__).resolve().parents[1]


def test_options_md_is_the_generated_one():
    """docs/options.md is generated from the option table (the long explanations; ``--help`` shows the short
    ones): regenerate it with the command its first lines name when this fails."""
    assert (ROOT / "docs" / "options.md").read_text(encoding="utf-8") == options_markdown()


def test_options_md_covers_every_option_and_group():
    text = options_markdown()
    for key, title in GROUPS.items():
        assert f"## {title[0].upper()}{title[1:]}\n" in text, key
    for o in OPTIONS:
        assert f"### {o.name}\n" in text and help_text(o).split(" ")[0] in text, o.name
        if o.flag:
            assert f"](#{o.name}) | {o.short} |" in text.replace("\\|", "|"), o.name


def test_readme_holds_no_stale_option_table():
    """The README links docs/options.md; a table of options there would be a second copy that drifts, so any
    it holds must be the generated one."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    if "| option | meaning | default |\n|---|---|---|\n| [`--" in readme or "| `--fill " in readme:
        assert markdown_table() in readme
