#!/usr/bin/env bash
# Issue 43, step 1: the learning curve of `full` with independent actors and critics (exp1_tuned otherwise unchanged),
# 2 seeds up to the paper's 2.5M env steps, from which the study's budget is chosen (rule in README.md).
# Run it from a worktree pinned to a commit, writing results into the main checkout:
#   git worktree add --detach ../sweep-indep <commit>
#   cd ../sweep-indep && RESULTS_ROOT=/work/main/benchmarks nohup bash benchmarks/paper_n5_independent/run_curve.sh &
# Resumable: run it again and finished runs are skipped; a run killed with its session goes on from its last
# snapshot (each tenth of its budget). Each start appends its commit to results/commits.log.
set -u
cd "$(dirname "$0")/../.."
RESULTS_ROOT="${RESULTS_ROOT:-benchmarks}"
CONFIG="${1:-benchmarks/paper_n5_independent/curve.json}"
WORKERS="${WORKERS:-2}"
RESULTS="$RESULTS_ROOT/paper_n5_independent/results"
mkdir -p "$RESULTS"
echo "$(date -u +%FT%TZ) commit $(git rev-parse HEAD) curve $CONFIG workers $WORKERS" >>"$RESULTS/commits.log"
export SDL_VIDEODRIVER=dummy
nice -n 19 python -m sb3_maddpg run --config "$CONFIG" \
    --results "$RESULTS" --workers "$WORKERS" --threads 1 --quiet
