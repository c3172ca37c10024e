#!/usr/bin/env bash
# Issue 43's reading from the committed runs, written into docs/_static/paper_n5_independent: the study's report (the
# seeds every scheme of a setting has finished; its settings only, not the learning curve's runs beside them) and the
# study beside the shared one (beside_shared.md: Table 2 of both, the 2 x 2 of networks x the target's selection rule).
# Run it from the repository root in every commit that adds finished runs: tests/experiments/test_experiments.py fails
# on a stale report, tests/experiments/test_beside_shared.py on a stale beside_shared.md,
# tests/experiments/test_before_after.py on a stale before_after.md, tests/test_readme_claims.py on a stale README
# or docs table and tests/experiments/test_fixed_graph.py on a stale fixed_graph.md.
set -euo pipefail
cd "$(dirname "$0")/../.."
export SDL_VIDEODRIVER=dummy
OUT=docs/_static/paper_n5_independent
python -m sb3_maddpg report benchmarks/paper_n5_independent/results --complete-seeds --out "$OUT" \
    --experiment paper_n5i_exp1 --experiment paper_n5i_exp2 \
    --metric success_rate_r0.3 --metric success_rate --metric min_dist_sum --metric return_mean
rm -f "$OUT/marl_eval.json"  # marl-eval's input, not shown in the docs
# Issue 56's "before": the study as it stood at its first five seeds, beside the report above at every complete seed.
python -m sb3_maddpg report benchmarks/paper_n5_independent/results --seeds 0-4 --no-plots --out "$OUT/seeds_0-4" \
    --experiment paper_n5i_exp1 --experiment paper_n5i_exp2 --metric success_rate_r0.3 --metric min_dist_sum
rm -f "$OUT/seeds_0-4/marl_eval.json"
python benchmarks/paper_n5_independent/beside_shared.py --out "$OUT/beside_shared.md"
python benchmarks/paper_n5_independent/before_after.py --out "$OUT/before_after.md"  # each family before seeds 5-9, after
python benchmarks/paper_n5_independent/claims_tables.py  # the README's and the docs page's tables (tests/test_readme_claims.py)
# Issue 56, item 4: the fixed neighbour graph against Exp. 1, once it has a finished run (tests/experiments/test_fixed_graph.py).
if compgen -G "benchmarks/paper_n5_independent/results_fixed_graph/*/*/seed_*/done" > /dev/null; then
    python benchmarks/paper_n5_independent/fixed_graph.py --out "$OUT/fixed_graph.md"
fi
