"""Issue 57, item 3: the table "Which information helps, task by task", regenerated from the committed runs.

Writes ``docs/guide/cross_task_table.inc`` (included by ``docs/guide/cross_task.rst``) and
``benchmarks/cross_task/table.json`` (what ``tests/results/test_cross_task.py`` compares with the runs). Run it from
the repository's root after committing runs: ``python benchmarks/cross_task/make_table.py``.
"""

import json
from pathlib import Path

from sb3_maddpg.experiments.config import ordered_schemes
from sb3_maddpg.results.cross_task import TaskStudy, format_table_rst, row_data, task_row

BENCHMARKS = Path(__file__).resolve().parent.parent
TABLE_JSON = BENCHMARKS / "cross_task" / "table.json"
TABLE_RST = BENCHMARKS.parent / "docs" / "guide" / "cross_task_table.inc"

STUDIES = (
    TaskStudy("simple_spread N=3, full observability", BENCHMARKS / "paper_n3/results", "n3_full", "min_dist_sum"),
    TaskStudy("simple_spread N=3, 1 other agent observed", BENCHMARKS / "paper_n3/results", "n3_partial", "min_dist_sum"),
    TaskStudy(
        "simple_spread N=5, Exp. 1 (paper's networks)",
        BENCHMARKS / "paper_n5_independent/results",
        "paper_n5i_exp1",
        "min_dist_sum",
    ),
    TaskStudy(
        "simple_spread N=5, Exp. 2 (paper's networks)",
        BENCHMARKS / "paper_n5_independent/results",
        "paper_n5i_exp2",
        "min_dist_sum",
    ),
    TaskStudy("SISL pursuit (8 x 8, 4 pursuers, 4 evaders)", BENCHMARKS / "pursuit/results", "pursuit", "return_mean"),
)
"""The tasks, in the table's order: each the study that ran it and the metric it is read by."""


def table() -> tuple[list[dict], str]:
    """:return: The rows as JSON values and the RST table."""
    rows = [task_row(study) for study in STUDIES]
    schemes = ordered_schemes({scheme for row in rows for scheme in row.cells})
    return [row_data(row) for row in rows], format_table_rst(rows, schemes)


def main() -> None:
    data, rst = table()
    TABLE_JSON.write_text(json.dumps(data, indent=2) + "\n")
    TABLE_RST.write_text(rst)
    for row in data:
        print(f"{row['task']}: {len(row['seeds'])} complete seeds, 1 = {row['top_is'] or '-'}")


if __name__ == "__main__":
    main()
