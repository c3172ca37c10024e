"""Docs a user reads (issue 58): each guide page at most 2,500 words, the guide at most 15,000, the README at most
1,000 (words as ``wc -w`` counts them). Diagnoses, probes and study logs go to the ``benchmarks/`` READMEs.

The guide's limits count its prose, the ``.rst`` files: tables that a script writes from the runs and a page includes
(``.. include::`` of a generated ``.inc``, ``.. markdown-include::``, ``.. results-directory::``) are results, tested
against the runs, and not counted; the README's table is inline and counted. The paper's question page is the one
exception: issue 56 asks for a results page read in ten minutes, so its limit counts its claims table."""

import re
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PAGE_LIMIT, GUIDE_LIMIT, README_LIMIT = 2_500, 15_000, 1_000
PAPER_N5_LIMIT = 2_000
"""Issue 56: the results page of the paper's question with its claims table (``.. include::``), read in ten minutes; the
generated reports it appends under "The reports" are an appendix, not counted."""


def words(path: Path) -> int:
    return len(path.read_text().split())


def test_every_guide_page_and_the_guide_are_within_their_limits() -> None:
    pages = {path.name: words(path) for path in sorted((REPO / "docs" / "guide").glob("*.rst"))}
    assert len(pages) > 10
    assert {name: count for name, count in pages.items() if count > PAGE_LIMIT} == {}
    assert sum(pages.values()) <= GUIDE_LIMIT, sum(pages.values())


def test_the_readme_is_within_its_limit() -> None:
    assert words(REPO / "README.md") <= README_LIMIT


def test_the_paper_s_question_page_with_its_tables_is_within_its_limit() -> None:
    page = REPO / "docs" / "guide" / "paper_n5.rst"
    included = re.findall(r"^\.\. include:: (\S+)$", page.read_text(), flags=re.MULTILINE)
    assert included  # the claims table, written from the report
    assert words(page) + sum(words(page.parent / name) for name in included) <= PAPER_N5_LIMIT
