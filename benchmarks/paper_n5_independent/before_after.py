"""Issue 56's measure: each family's raw and Holm-adjusted p at seeds 0-4 and at every complete seed, from the claims.

Reads the report's claims at seeds 0-4 (``docs/_static/paper_n5_independent/seeds_0-4/claims_<metric>.csv``) and at
every complete seed (``claims_<metric>.csv`` beside them) and writes ``before_after.md`` there: for each family (one
setting x one metric, each scheme against ``full``) the runs a side, the means, the raw and the adjusted p and the
verdict at both. ``report.sh`` runs it; ``tests/experiments/test_before_after.py`` fails on a stale page.
"""

import argparse
import csv
from collections.abc import Callable
from pathlib import Path

from sb3_maddpg.experiments.config import BASELINE_SCHEME
from sb3_maddpg.results.claims import format_p_value

ROOT = Path(__file__).resolve().parent.parent.parent
REPORT = ROOT / "docs" / "_static" / "paper_n5_independent"
BEFORE = "seeds_0-4"
METRICS = {"min_dist_sum": "min-dist sum, lower is better", "success_rate_r0.3": "success within 0.3 (%), higher is better"}
"""The metrics the report reads at seeds 0-4 (``report.sh``), in the order the page shows them."""
SETTINGS = {"paper_n5i_exp1": "Exp. 1", "paper_n5i_exp2": "Exp. 2"}
DECLARED_SETTING, DECLARED_RUNS = "paper_n5i_exp1", 10
"""Issue 56's declared reading: Exp. 1 at seeds 0-9, each claim against ``full`` 10 runs a side."""
Claims = dict[tuple[str, str, str], dict[str, str]]
"""A claims CSV's claims against ``full`` by (setting, better, worse)."""
HEADER = (
    "| claim | runs (before; after) | means (before; after) | p (before; after) | Holm p (before; after) "
    "| verdict before | verdict after |",
    "|---|---|---|---|---|---|---|",
)


def read_claims(path: Path) -> Claims:
    """
    :param path: A claims CSV the report wrote.
    :return: Its claims against ``full`` by (setting, better, worse); an empty mapping where there is no such file.
    """
    if not path.exists():
        return {}
    with open(path, newline="") as file:
        rows = list(csv.DictReader(file))
    return {
        (row["setting"], row["better"], row["worse"]): row for row in rows if BASELINE_SCHEME in (row["better"], row["worse"])
    }


def _cell(before: dict[str, str] | None, after: dict[str, str] | None, text: Callable[[dict[str, str]], str]) -> str:
    """
    :param before: The claim's row at seeds 0-4, ``None`` where that reading has no such claim.
    :param after: The claim's row at every complete seed, or ``None``.
    :param text: What the cell shows of a row.
    :return: ``"<before>; <after>"``, ``-`` for a reading without the claim.
    """
    return f"{text(before) if before else '-'}; {text(after) if after else '-'}"


def family_rows(before: Claims, after: Claims, setting: str) -> list[str]:
    """
    :param before: The claims at seeds 0-4, as :func:`read_claims` returns them.
    :param after: The claims at every complete seed.
    :param setting: The family's setting (its metric is the CSVs').
    :return: The family's table rows: each claim against ``full`` that either reading asked, in the report's order.
    """
    keys = [key for key in after if key[0] == setting] + [key for key in before if key[0] == setting and key not in after]
    rows = []
    for key in keys:
        old, new = before.get(key), after.get(key)
        cells = [
            f"`{key[1]}` > `{key[2]}`",
            _cell(old, new, lambda row: f"{row['n_better']} v {row['n_worse']}"),
            _cell(old, new, lambda row: f"{float(row['mean_better']):.2f} vs {float(row['mean_worse']):.2f}"),
            _cell(old, new, lambda row: format_p_value(float(row["p_value"]))),
            _cell(old, new, lambda row: f"{format_p_value(float(row['p_holm']))} ({row['family_size']})"),
            old["verdict"] if old else "-",
            new["verdict"] if new else "-",
        ]
        rows.append("| " + " | ".join(cells) + " |")
    return rows


def _runs(row: dict[str, str] | None) -> tuple[str, str] | None:
    """
    :param row: A claim's row, or ``None``.
    :return: Its runs a side, ``None`` for none.
    """
    return (row["n_better"], row["n_worse"]) if row else None


def before_after_page(report: Path = REPORT) -> str:
    """
    :param report: The report's directory, ``seeds_0-4/`` inside it.
    :return: The page: a table per family that either reading has, then what the columns mean.
    """
    after_runs = {
        int(row[side])
        for key, row in read_claims(report / f"claims_{next(iter(METRICS))}.csv").items()
        if key[0] == DECLARED_SETTING
        for side in ("n_better", "n_worse")
    }
    if after_runs == {DECLARED_RUNS}:
        when = (
            f"{SETTINGS[DECLARED_SETTING]}'s {DECLARED_RUNS} seeds are the reading issue 56 declared; a verdict that "
            "changed between the two readings is read there, and nothing corrects for the look at seeds 0-4."
        )
    else:
        when = (
            f"until {SETTINGS[DECLARED_SETTING]} has {DECLARED_RUNS} seeds it is an interim look, and nothing corrects "
            "for looking more than once: a verdict that changes between looks is not settled."
        )
    parts = [
        "# Each family at seeds 0-4 and at every complete seed",
        "",
        f"Before: seeds 0-4 (`{BEFORE}/`). After: every seed all of a setting's schemes have finished (the report), "
        f"seeds 0-4 among them, so not an independent replication; {when}",
    ]
    for metric, label in METRICS.items():
        before = read_claims(report / BEFORE / f"claims_{metric}.csv")
        after = read_claims(report / f"claims_{metric}.csv")
        for setting, name in SETTINGS.items():
            rows = family_rows(before, after, setting)
            if rows:
                same = all(_runs(before.get(key)) == _runs(after.get(key)) for key in before if key[0] == setting)
                note = " (seeds 0-4 in both: the same runs twice)" if same and before else ""
                parts += ["", f"#### {name}, {label}{note}", "", *HEADER, *rows]
    parts += [
        "",
        "A family is one setting x one metric: each scheme against `full`, declared before any score is read; Holm p is "
        "adjusted within it (its size in brackets), and the verdict follows the adjusted p: *holds* or *reverses* below "
        ".05; else the claim *leans* one way or is *not separated*, read with the raw p beside it. p: the exact "
        "two-sided Mann-Whitney U test. `-`: that reading has no such claim (its schemes had not finished).",
        "",
    ]
    return "\n".join(parts)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPORT / "before_after.md", help="where to write the page")
    out = parser.parse_args().out
    out.write_text(before_after_page())
    print(f"wrote {out}")
