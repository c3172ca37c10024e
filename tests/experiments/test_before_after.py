"""Issue 56's measure (``benchmarks/paper_n5_independent/before_after.py``): each family's p before seeds 5-9 and
after, joined claim by claim from the two claims CSVs, and the committed page against the committed claims."""

from pathlib import Path
from types import ModuleType

import pytest

from tests.script_module import load_script

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "benchmarks" / "paper_n5_independent" / "before_after.py"
HEADER = (
    "setting,observability,better,worse,relation,paper_evidence,metric,n_better,n_worse,mean_better,mean_worse,"
    "p_value,p_holm,family_size,improvement,improvement_low,improvement_high,verdict,seeds_needed\n"
)


@pytest.fixture(scope="module")
def before_after() -> ModuleType:
    return load_script(SCRIPT)


def write_claims(path: Path, rows: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEADER + rows)


def test_each_claim_is_read_before_and_after_and_a_claim_one_reading_lacks_says_so(
    before_after: ModuleType, tmp_path: Path
) -> None:
    write_claims(
        tmp_path / "seeds_0-4" / "claims_min_dist_sum.csv",
        "paper_n5i_exp1,full,actions,full,>,e,min_dist_sum,5,5,0.59,0.52,0.0317,0.0952,3,0,0,0,leans the other way,\n"
        + "paper_n5i_exp1,full,selected,observations,>,e,min_dist_sum,5,5,1.1,0.7,0.0079,0.0079,1,0,0,0,reverses,\n"
        + "paper_n5i_exp2,partial,selected,full,>,e,min_dist_sum,5,5,1.05,1.13,0.095,0.19,2,0,0,0,leans the claim's way,\n",
    )
    write_claims(
        tmp_path / "claims_min_dist_sum.csv",
        "paper_n5i_exp1,full,actions,full,>,e,min_dist_sum,10,10,0.6,0.5,0.0001,0.0004,4,0,0,0,reverses,\n"
        + "paper_n5i_exp1,full,full,independent,>,e,min_dist_sum,10,10,0.5,0.64,0.001,0.003,4,1,1,1,holds,\n"
        + "paper_n5i_exp2,partial,selected,full,>,e,min_dist_sum,5,5,1.05,1.13,0.095,0.19,2,0,0,0,leans the claim's way,\n",
    )
    page = before_after.before_after_page(tmp_path)
    assert "#### Exp. 1, min-dist sum, lower is better\n" in page  # seeds added: no note
    assert "#### Exp. 2, min-dist sum, lower is better (seeds 0-4 in both: the same runs twice)\n" in page
    assert "Exp. 1's 10 seeds are the reading issue 56 declared" in page and "interim" not in page
    assert "success within 0.3" not in page  # no claims on that metric in either reading
    rows = [line for line in page.splitlines() if line.startswith("| `")][:2]
    assert rows == [
        "| `actions` > `full` | 5 v 5; 10 v 10 | 0.59 vs 0.52; 0.60 vs 0.50 | .032; < .001 | .095 (3); < .001 (4) "
        "| leans the other way | reverses |",
        "| `full` > `independent` | -; 10 v 10 | -; 0.50 vs 0.64 | -; .001 | -; .003 (4) | - | holds |",
    ]  # the claim between two schemes other than `full` is a family of its own: not shown


def test_the_committed_page_is_the_committed_claims(before_after: ModuleType) -> None:
    committed = REPO / "docs" / "_static" / "paper_n5_independent" / "before_after.md"
    assert committed.read_text() == before_after.before_after_page(), (
        "docs/_static/paper_n5_independent/before_after.md differs from the committed claims: run "
        "bash benchmarks/paper_n5_independent/report.sh"
    )


def test_a_reading_short_of_exp_1_s_ten_seeds_says_it_is_an_interim_look(before_after: ModuleType, tmp_path: Path) -> None:
    rows = "paper_n5i_exp1,full,actions,full,>,e,min_dist_sum,{n},{n},0.6,0.5,0.0001,0.0004,4,0,0,0,reverses,\n"
    write_claims(tmp_path / "seeds_0-4" / "claims_min_dist_sum.csv", rows.format(n=5))
    write_claims(tmp_path / "claims_min_dist_sum.csv", rows.format(n=9))
    page = before_after.before_after_page(tmp_path)
    assert "until Exp. 1 has 10 seeds it is an interim look" in page and "declared;" not in page
