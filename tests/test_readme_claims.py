"""The README's N=5 table and the docs page's say what the committed claims say (issue 56: they state only what
survives a correction): they are what ``benchmarks/paper_n5_independent/claims_tables.py`` writes from the report's
claims CSVs."""

import csv
import io
from pathlib import Path
from types import ModuleType

import pytest

from tests.script_module import load_script

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def claims_tables() -> ModuleType:
    return load_script(REPO / "benchmarks" / "paper_n5_independent" / "claims_tables.py")


def claims(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text)))


HEADER = (
    "setting,observability,better,worse,relation,paper_evidence,metric,n_better,n_worse,mean_better,mean_worse,"
    "p_value,p_holm,family_size,improvement,improvement_low,improvement_high,verdict,seeds_needed\n"
)


def test_the_readme_table_is_the_committed_claims(claims_tables: ModuleType) -> None:
    readme = (REPO / "README.md").read_text()
    assert claims_tables.readme_with_table(readme, claims_tables.read_claims()) == readme, (
        "README.md's N=5 table differs from docs/_static/paper_n5_independent/claims_min_dist_sum.csv: run "
        "python benchmarks/paper_n5_independent/claims_tables.py"
    )


def test_the_docs_page_s_table_is_the_committed_claims_its_prose_reads(claims_tables: ModuleType) -> None:
    table = claims_tables.docs_table(claims_tables.read_claims(), claims_tables.DOCS_SEEDS)
    assert claims_tables.DOCS_TABLE.read_text() == table, (
        f"docs/guide/paper_n5_claims.inc differs from {claims_tables.CLAIMS_CSV}: run "
        "python benchmarks/paper_n5_independent/claims_tables.py"
    )
    assert ".. include:: paper_n5_claims.inc" in (REPO / "docs" / "guide" / "paper_n5.rst").read_text()


def test_the_docs_table_has_the_readme_s_rows_as_an_rst_list_table(claims_tables: ModuleType) -> None:
    rows = claims(
        HEADER + 'x,full,actions,full,>,"73.63 vs 63.89, p < .01",min_dist_sum,5,5,0.59,0.52,0.0079,0.0397,5,0,0,0,reverses,\n'
    )
    lines = claims_tables.docs_table(rows, "seeds 0-4").splitlines()
    assert lines[0] == ".. list-table:: The paper's claims with a network per agent, seeds 0-4 (lower min-dist sum is better)"
    first = lines.index("   * - Exp. 1")
    assert lines[first : first + 7] == [
        "   * - Exp. 1",
        "     - ``actions`` > ``full``",  # Markdown's code spans become RST literals
        "     - 73.63 vs 63.89, p < .01",
        "     - 0.59 vs 0.52",  # the runs a side: in the line under the table
        "     - .008",
        "     - .040 (5)",
        "     - reverses",
    ]
    assert "     - not finished" in lines and "     -" in lines  # the unfinished claims, their empty cells bare
    assert lines[-1] == claims_tables.floor_line(rows)


def test_a_verdict_the_correction_removes_is_a_lean_and_unfinished_claims_are_open(claims_tables: ModuleType) -> None:
    rows = claims(
        HEADER
        + 'x,full,actions,full,>,"73.63 vs 63.89, p < .01",min_dist_sum,5,5,0.59,0.52,0.0079,0.0397,5,0,0,0,reverses,\n'
        + 'x,full,full,independent,>,"63.89 vs 44.58, p < .01",min_dist_sum,5,5,0.52,0.64,0.0317,0.0952,5,1,1,1,'
        + "leans the claim's way,9\n"
        + 'x,full,independent,observations,>,"44.58 vs 36.89",min_dist_sum,5,5,0.6,0.7,0.1,0.1,1,1,1,1,holds,\n'
    )
    table = claims_tables.table_rows(rows)
    assert table[0] == (
        "| Exp. 1 | `actions` > `full` | 73.63 vs 63.89, p < .01 | 0.59 vs 0.52 | .008 | .040 (5) | reverses |"
    )
    # Raw p .032 but Holm .095: no verdict word, the lean with its raw p.
    assert table[1].endswith("| .032 | .095 (5) | leans the claim's way (p = .032) |")
    assert not any("`independent` > `observations`" in row for row in table)  # not against full: not the README's
    # What has no runs is open: Exp. 1's `selected` > `full` and `full` > `observations`, and all of Exp. 2.
    # Each setting is named on its first row only.
    assert table[1].startswith("| | `full` > `independent` |")
    assert table[2:] == [
        "| | `selected` > `full` | 71.58 vs 63.89, p < .05 | not finished | | | open |",
        "| | `full` > `observations` | 63.89 vs 36.89 | not finished | | | open |",
        "| Exp. 2 | `selected` > `full` | 74.99 vs 70.11, not significant | not finished | | | open |",
        "| | `full` > `observations`, `actions`, `independent` | 70.11 vs 67.70, 51.88, 51.02 | not finished | | | open |",
    ]


def test_the_line_under_the_table_says_each_setting_s_runs_and_floor(claims_tables: ModuleType) -> None:
    """The smallest p two groups allow is 2 / C(n1 + n2, n1): 2/924 at 6 a side; times the family after Holm. A
    setting with unequal groups says the range of runs, and 5 v 6 allows 2/462 (.0043), not 5 v 5's 2/252."""
    rows = claims(
        HEADER
        + 'x,full,actions,full,>,"e",min_dist_sum,6,6,0.59,0.52,0.002,0.011,5,0,0,0,reverses,\n'
        + 'x,full,full,independent,>,"e",min_dist_sum,6,6,0.52,0.64,0.002,0.011,5,1,1,1,holds,\n'
        + 'y,partial,selected,full,>,"e",min_dist_sum,5,6,1.05,1.13,0.1,0.2,2,0,0,0,leans the claim\'s way,\n'
    )
    assert claims_tables.floor_line(rows) == (
        "Runs a side (the smallest p, no overlap; after Holm over the family): Exp. 1 6 (.002; .011), Exp. 2 5-6 (.004; .009)."
    )


def test_a_setting_whose_rows_read_different_runs_is_refused(claims_tables: ModuleType) -> None:
    """The rows leave their runs to the line under the table, so they must all read the same runs."""
    rows = claims(
        HEADER
        + 'x,full,actions,full,>,"e",min_dist_sum,6,6,0.59,0.52,0.002,0.011,5,0,0,0,reverses,\n'
        + 'x,full,full,independent,>,"e",min_dist_sum,6,5,0.52,0.64,0.002,0.011,5,1,1,1,holds,\n'
    )
    with pytest.raises(ValueError, match=r"Exp. 1's claims against full read different runs .*run report.sh"):
        claims_tables.table_cells(rows)


def test_a_readme_without_the_markers_is_refused_saying_where(claims_tables: ModuleType) -> None:
    with pytest.raises(ValueError, match="README.md has no <!-- table: .* markers around the table"):
        claims_tables.readme_with_table("# README\n\nno table here\n", [])
