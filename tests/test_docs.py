"""The docs are reference pages, not lab notebooks: every page under docs/ (the dated decision
records in docs/design/ excepted) stays under 500 lines, names no issue, wave or numbered pass,
and its links to other pages of the repository resolve; docs/localizer-config.md lists every
field of `LocalizerConfig` with the default the code has."""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import pytest

from localizer.config import LocalizerConfig

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
REFERENCE_PAGES = sorted(DOCS.glob("*.md"))
MAX_LINES = 500

# "#12", "issue 14", "issues 12 and 14", "wave 2", "the third pass", "(speed pass)".
HISTORY = re.compile(
    r"(?<![\w&/])#\d+\b"
    r"|\bissues? \d+"
    r"|\bwaves?\b(?![-_.])"
    r"|\b(first|second|third|fourth|fifth|sixth|speed|accuracy|later|next|last) pass(es)?\b",
    re.IGNORECASE,
)
# Markdown links and "docs/NAME.md" citations to pages of this repository.
LINK = re.compile(r"\]\(((?!https?:|#)[^)#\s]+)(?:#[^)]*)?\)")
CITATION = re.compile(r"\bdocs/[\w./-]+\.md\b")


def test_there_are_reference_pages() -> None:
    assert len(REFERENCE_PAGES) >= 10, [p.name for p in REFERENCE_PAGES]


@pytest.mark.parametrize("page", REFERENCE_PAGES, ids=lambda p: p.name)
def test_a_reference_page_stays_under_500_lines(page: Path) -> None:
    lines = page.read_text(encoding="utf-8").count("\n")
    assert lines <= MAX_LINES, f"{page.name}: {lines} lines (split it by concept)"


@pytest.mark.parametrize("page", REFERENCE_PAGES, ids=lambda p: p.name)
def test_a_reference_page_names_no_issue_wave_or_pass(page: Path) -> None:
    hits = [
        f"{page.name}:{n}: {m.group(0)!r}"
        for n, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1)
        for m in HISTORY.finditer(line)
    ]
    assert not hits, "history belongs in docs/design/: " + "; ".join(hits)


def test_the_history_pattern_catches_what_it_should() -> None:
    diaries = ["see #12", "(issue 14)", "issues 12 and 14", "the second wave", "the third pass"]
    for diary in [*diaries, "Tracking time (speed pass)"]:
        assert HISTORY.search(diary), diary
    references = ["results/wave7_pair_sigma.json", "passes within 0.8 m", "a pass of metres"]
    for reference in [*references, "`&#8203;`", "docs/api.md#events", "passes its frames"]:
        assert not HISTORY.search(reference), reference


@pytest.mark.parametrize("page", [*REFERENCE_PAGES, ROOT / "README.md"], ids=lambda p: p.name)
def test_links_and_citations_to_docs_resolve(page: Path) -> None:
    text = page.read_text(encoding="utf-8")
    missing = [
        target
        for target in LINK.findall(text)
        if not (page.parent / target).exists() and not (ROOT / target).exists()
    ]
    missing += [c for c in CITATION.findall(text) if not (ROOT / c).exists()]
    assert not missing, f"{page.name}: no such file: {sorted(set(missing))}"


def _default_cell(value: object) -> str:
    """A default as docs/localizer-config.md writes it."""
    if isinstance(value, float):
        return "pi" if value == math.pi else f"{value:g}"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple):
        return "(" + ", ".join(_default_cell(v) for v in value) + ")"
    return repr(value)


def _row(config: object, name: str) -> str:
    """The page's row for a field: its docstring's "name: ..." entry and its default."""
    doc = " ".join((type(config).__doc__ or "").split())
    found = re.search(rf"\b{name}: (.*?)(?= \w+(?:, \w+)*: |$)", doc)
    what = found.group(1) if found else "(document it in the class's Attributes)"
    return f"| `{name}` | UNIT | {_default_cell(getattr(config, name))} | {what} |"


def test_the_configuration_page_lists_every_field_with_its_default() -> None:
    page = (DOCS / "localizer-config.md").read_text(encoding="utf-8")
    sections = dict(re.findall(r"^## `(\w+)`: `\w+`\n(.*?)(?=^## |\Z)", page, re.M | re.S))
    config = LocalizerConfig()
    problems = []
    for stage in dataclasses.fields(LocalizerConfig):
        sub = getattr(config, stage.name)
        if stage.name not in sections:
            problems.append(f"add a section: ## `{stage.name}`: `{type(sub).__name__}`")
        rows = dict(
            re.findall(r"^\| `(\w+)` \| [^|]* \| ([^|]*) \|", sections.get(stage.name, ""), re.M)
        )
        for f in dataclasses.fields(sub):
            want = _default_cell(getattr(sub, f.name))
            got = rows.get(f.name)
            if got is None:
                problems.append(f"{stage.name}.{f.name} missing: add the row {_row(sub, f.name)}")
            elif got.strip() != want:
                problems.append(f"{stage.name}.{f.name}: page {got.strip()}, code {want}")
        names = {f.name for f in dataclasses.fields(sub)}
        problems += [f"{stage.name}.{name} not in the code" for name in rows.keys() - names]
    assert not problems, "docs/localizer-config.md: " + "; ".join(problems)
