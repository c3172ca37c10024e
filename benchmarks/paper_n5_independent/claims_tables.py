"""The README's table "Which information helps at N=5" and the docs page's, written from the study's committed claims.

Reads the claims CSVs that ``report.sh`` writes from the runs and writes two tables of the same rows: each of the
paper's claims against ``full``, its runs' means (each setting's runs a side are in the line under the table), the
exact p, the Holm-adjusted p with its family's size, and the verdict the adjusted p allows; a claim whose schemes have
not finished is one row per setting, "not finished".

- The README's, between its two markers, from every complete seed (``claims_min_dist_sum.csv``).
- ``docs/guide/paper_n5_claims.inc``, the table of ``docs/guide/paper_n5.rst``, from the same claims.

Run it after ``report.sh`` (``python benchmarks/paper_n5_independent/claims_tables.py``);
``tests/test_readme_claims.py`` fails while either table says other numbers than the committed claims.
"""

import csv
import math
import sys
from pathlib import Path

from sb3_maddpg.experiments.config import BASELINE_SCHEME
from sb3_maddpg.results.claims import PAPER_CLAIMS, PAPER_TABLE2, UNDECIDED_VERDICTS, Observability, format_p_value

ROOT = Path(__file__).resolve().parent.parent.parent
REPORT = ROOT / "docs" / "_static" / "paper_n5_independent"
CLAIMS_CSV = REPORT / "claims_min_dist_sum.csv"
DOCS_SEEDS = "every complete seed"
"""The docs table's caption for the seeds it reads: every seed that all of a setting's schemes have finished (the line
under the table gives each setting's runs a side)."""
README = ROOT / "README.md"
DOCS_TABLE = ROOT / "docs" / "guide" / "paper_n5_claims.inc"
START, END = "<!-- table: benchmarks/paper_n5_independent/claims_tables.py -->", "<!-- end -->"
SETTINGS: dict[Observability, str] = {"full": "Exp. 1", "partial": "Exp. 2"}
"""The paper's settings by observability, as the table names them."""
HEADER = (
    "| setting | the paper's claim | paper (success %, 31 seeds) | a network per agent (min-dist sum) | p | Holm p "
    "| verdict |",
    "|---|---|---|---|---|---|---|",
)


def table_cells(claims: list[dict[str, str]]) -> list[list[str]]:
    """
    :param claims: The rows of the claims CSV.
    :return: The tables' rows as cells, Exp. 1 then Exp. 2, each setting named on its first row: each claim against
        ``full`` that the runs asked, then those whose schemes have not finished ("open"; the claims that ``full``
        beats others in one row).
    :raise ValueError: When a setting's claims against ``full`` read different runs a side (no complete seeds).
    """
    rows = []
    for observability, setting in SETTINGS.items():
        asked = [row for row in claims if row["observability"] == observability]
        sizes = {(row["n_better"], row["n_worse"]) for row in asked if BASELINE_SCHEME in (row["better"], row["worse"])}
        if len(sizes) > 1:  # the rows leave their runs to the line under the table, which then would hide this
            raise ValueError(
                f"{setting}'s claims against {BASELINE_SCHEME} read different runs ({sorted(sizes)}): the tables read a "
                "report of complete seeds (report.sh's --complete-seeds); run report.sh."
            )
        for row in asked:
            if BASELINE_SCHEME not in (row["better"], row["worse"]):
                continue  # a claim between two other schemes: a family of its own, not the tables'
            p_value, holm = float(row["p_value"]), float(row["p_holm"])
            verdict = row["verdict"]
            if verdict in UNDECIDED_VERDICTS:
                verdict = f"{verdict} (p = {format_p_value(p_value)})"
            means = f"{float(row['mean_better']):.2f} vs {float(row['mean_worse']):.2f}"  # runs: the line under it
            evidence = row["paper_evidence"] if row["better"] != "selected_next" else "(not in the paper)"
            claim_text = f"`{row['better']}` > `{row['worse']}`"
            holm_text = f"{format_p_value(holm)} ({row['family_size']})"
            rows.append([setting, claim_text, evidence, means, format_p_value(p_value), holm_text, verdict])
        done = {(row["better"], row["worse"]) for row in asked}
        unfinished = [
            claim
            for claim in PAPER_CLAIMS
            if claim.observability == observability
            and BASELINE_SCHEME in (claim.better, claim.worse)
            and (claim.better, claim.worse) not in done
        ]
        for claim in unfinished:
            if claim.worse == BASELINE_SCHEME:
                rows.append([setting, f"`{claim.better}` > `{claim.worse}`", claim.evidence, "not finished", "", "", "open"])
        below = [claim.worse for claim in unfinished if claim.better == BASELINE_SCHEME]  # one row: `full` > each
        if below:
            paper = PAPER_TABLE2[observability]
            claim_text = f"`{BASELINE_SCHEME}` > " + ", ".join(f"`{scheme}`" for scheme in below)
            evidence = f"{paper[BASELINE_SCHEME][0]:.2f} vs " + ", ".join(f"{paper[scheme][0]:.2f}" for scheme in below)
            rows.append([setting, claim_text, evidence, "not finished", "", "", "open"])
    # A setting is named on its first row only: the rows under it are its own.
    return [["" if i and row[0] == rows[i - 1][0] else row[0], *row[1:]] for i, row in enumerate(rows)]


def table_rows(claims: list[dict[str, str]]) -> list[str]:
    """
    :param claims: The rows of the claims CSV.
    :return: The README's table rows (Markdown) of :func:`table_cells`.
    """
    return ["|" + "|".join(f" {cell} " if cell else " " for cell in cells) + "|" for cells in table_cells(claims)]


def docs_table(claims: list[dict[str, str]], seeds: str) -> str:
    """
    :param claims: The rows of the claims CSV.
    :param seeds: Which seeds the claims read, for the caption (``"seeds 0-4"``).
    :return: The docs page's table (an RST ``list-table`` of :func:`table_cells`) and the line under it.
    """
    header = [cell.strip() for cell in HEADER[0].strip("|").split("|")]
    caption = f"The paper's claims with a network per agent, {seeds} (lower min-dist sum is better)"
    lines = [f".. list-table:: {caption}", "   :header-rows: 1", ""]
    for cells in [header, *table_cells(claims)]:
        rst = [cell.replace("`", "``") for cell in cells]  # Markdown's code spans are RST's literals
        lines += [f"   * - {rst[0]}".rstrip(), *(f"     - {cell}".rstrip() for cell in rst[1:])]
    return "\n".join([*lines, "", floor_line(claims), ""])


def floor_line(claims: list[dict[str, str]]) -> str:
    """
    :param claims: The rows of the claims CSV.
    :return: A line under the table: each setting's runs a side against ``full`` and the smallest p they allow (no
        overlap: 2 / C(n1 + n2, n1)), raw and after Holm over the setting's family, so that the prose needs no seed
        count. Where the comparisons' sizes differ, the largest of their floors: the one every test can reach.
    """
    parts = []
    for observability, setting in SETTINGS.items():
        rows = [
            row for row in claims if row["observability"] == observability and BASELINE_SCHEME in (row["better"], row["worse"])
        ]
        if not rows:
            continue
        pairs = {(int(row["n_better"]), int(row["n_worse"])) for row in rows}
        floor = max(2 / math.comb(n_better + n_worse, n_better) for n_better, n_worse in pairs)
        family = max(int(row["family_size"]) for row in rows)
        sides = sorted({n for pair in pairs for n in pair})
        runs = f"{sides[0]}" if len(sides) == 1 else f"{sides[0]}-{sides[-1]}"
        parts.append(f"{setting} {runs} ({format_p_value(floor)}; {format_p_value(min(1.0, family * floor))})")
    return "Runs a side (the smallest p, no overlap; after Holm over the family): " + ", ".join(parts) + "."


def readme_with_table(readme: str, claims: list[dict[str, str]]) -> str:
    """
    :param readme: The README's text.
    :param claims: The rows of the claims CSV.
    :return: The README with the table between its markers written from ``claims``.
    """
    before, start, rest = readme.partition(START)
    _, end, after = rest.partition(END)
    if not start or not end:
        raise ValueError(f"README.md has no {START} ... {END} markers around the table: put them back around it.")
    table = "\n".join([*HEADER, *table_rows(claims)])
    return before + START + "\n" + table + "\n\n" + floor_line(claims) + "\n" + END + after


def read_claims(path: Path = CLAIMS_CSV) -> list[dict[str, str]]:
    """
    :param path: A claims CSV the report wrote: every complete seed's by default.
    :return: Its rows.
    """
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


if __name__ == "__main__":
    claims = read_claims()
    text = readme_with_table(README.read_text(), claims)
    changed = text != README.read_text()
    README.write_text(text)
    print(f"README.md's table {'rewritten' if changed else 'already as the claims say'} ({CLAIMS_CSV.name})")
    table = docs_table(claims, DOCS_SEEDS)
    changed = not DOCS_TABLE.exists() or table != DOCS_TABLE.read_text()
    DOCS_TABLE.write_text(table)
    print(f"{DOCS_TABLE.name} {'rewritten' if changed else 'already as the claims say'} ({CLAIMS_CSV.name})")
    sys.exit(0)
