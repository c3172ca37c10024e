#!/usr/bin/env bash
# Issue 43, step 2: the paper's question with independent actors and critics at N=5, both settings (exp1.json,
# exp2.json, written by make_configs.py at the budget curve_summary.md chose), 5 seeds first. Seeds outermost: a partial
# sweep stays balanced across schemes; exp1's runs come first, then exp2's (full, selected, selected_next first).
#
# Run it from a worktree pinned to a commit, writing results into the main checkout:
#   git worktree add --detach ../sweep-indep-study <commit>
#   cd ../sweep-indep-study && RESULTS_ROOT=/work/main/benchmarks WORKERS=2 nohup bash benchmarks/paper_n5_independent/run.sh &
# Resumable: run it again and finished runs are skipped; a run killed with its session goes on from its last snapshot.
# Each start appends its commit to results/commits.log; since b98b23a each run's config.json names it too.
#
# Issue 56, seeds 5-9 of Exp. 1 (seeds 0-4 are finished and skipped):
#   SETTINGS=exp1 SEEDS=0,1,2,3,4,5,6,7,8,9 RESULTS_ROOT=/work/main/benchmarks WORKERS=2 nohup bash ... &
# Issue 56, item 3: Exp. 2 whole (exp2.json holds all six schemes since make_configs.py --all-exp2; its three finished
# schemes are skipped), and item 4: Exp. 1's selected over a fixed neighbour graph (exp1_fixed_graph.json; from a
# commit that reads a {"neighbors": ...} selector, 2026-12-06 or later):
#   SETTINGS="exp2 exp1_fixed_graph" RESULTS_ROOT=/work/main/benchmarks WORKERS=1 nohup bash ... &
# (Since 2026-12-06 Exp. 2's three run into results_exp2_extra/ beside the Exp. 1 sweep: start the fixed graph alone,
# as the study README says, not with exp2.)
set -u
cd "$(dirname "$0")/../.."
RESULTS_ROOT="${RESULTS_ROOT:-benchmarks}"
WORKERS="${WORKERS:-2}"
SEEDS="${SEEDS:-0,1,2,3,4}"
SETTINGS="${SETTINGS:-exp1 exp2}"
RESULTS="$RESULTS_ROOT/paper_n5_independent/results"
configs=()
for setting in $SETTINGS; do
  configs+=(--config "benchmarks/paper_n5_independent/$setting.json")
  [ -f "benchmarks/paper_n5_independent/$setting.json" ] || {
    echo "benchmarks/paper_n5_independent/$setting.json is missing: run make_configs.py --steps <the budget> first" >&2
    exit 2
  }
done
mkdir -p "$RESULTS"
echo "$(date -u +%FT%TZ) commit $(git rev-parse HEAD) study $SETTINGS seeds $SEEDS workers $WORKERS" >>"$RESULTS/commits.log"
export SDL_VIDEODRIVER=dummy
nice -n 19 python -m sb3_maddpg run "${configs[@]}" --seeds "$SEEDS" \
    --results "$RESULTS" --workers "$WORKERS" --threads 1 --quiet
