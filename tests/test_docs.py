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


def test_readme_and_benchmarks_stay_short_and_current():
    """A newcomer's documents (issue 41): the README ≤ 160 lines with the two set-up commands as CI runs the second,
    BENCHMARKS.md ≤ 400 lines of current results; no development-log wording in either."""
    import re

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    bench = (ROOT / "BENCHMARKS.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 160
    assert len(bench.splitlines()) <= 400
    assert "python3 -m pip install . && heatparam demo" in readme
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    command = 'python3 -m pip install ".[test]" && python3 -m pytest -q'
    assert command in readme and command in ci
    for text in (readme, bench):
        assert not re.search(r"\b(stop|round) \d+\b", text, re.IGNORECASE)
    assert "§" not in readme
