#!/usr/bin/env bash
# The paper's question at N=5 (issue 31): its five schemes (independent, full, observations, actions, selected with the
# two nearest agents), and selected_next (selected with its target's agents selected again from the next observation:
# see benchmarks/paper_n5/README.md, "Why selected trails"), in both settings at the presets that learn N=5 (exp1_tuned, exp2_tuned), 1M env steps per run
# (40,000 episodes; ~39,000 gradient steps at one per 25 transitions), the paper's protocol (checkpoints over the last
# 20%, 20 for exp1 and 30 for exp2, 100 episodes each; learning curves of 50 points). Seeds outermost: a partial sweep
# stays balanced across schemes. exp1's runs come first, then exp2's.
#
# Run it from a worktree pinned to a commit, so that foreground edits never change a running sweep, and write the
# results into the main checkout to commit them as they finish:
#   git worktree add --detach ../sweep-paper-n5 <commit>
#   cd ../sweep-paper-n5 && RESULTS_ROOT=/work/main/benchmarks WORKERS=2 nohup bash benchmarks/paper_n5/run.sh &
# Resumable: run it again (from any commit whose run code gives the same results) and finished runs are skipped, and
# since commit bbab576 a run killed with its session goes on from its last snapshot (each tenth of its budget); more
# seeds extend the same results (SEEDS=0,1,...,9). Each start appends its commit to results/commits.log.
# Then (with --complete-seeds while it runs): sb3-maddpg report benchmarks/paper_n5/results --out docs/_static/paper_n5 --metric success_rate_r0.3 \
#           --metric success_rate --metric min_dist_sum --metric return_mean
set -u
cd "$(dirname "$0")/../.."
RESULTS_ROOT="${RESULTS_ROOT:-benchmarks}"
WORKERS="${WORKERS:-2}"
SEEDS="${SEEDS:-0,1,2,3,4}"
RESULTS="$RESULTS_ROOT/paper_n5/results"
mkdir -p "$RESULTS"
echo "$(date -u +%FT%TZ) commit $(git rev-parse HEAD) seeds $SEEDS workers $WORKERS" >>"$RESULTS/commits.log"
export SDL_VIDEODRIVER=dummy
nice -n 19 python -m sb3_maddpg run --config benchmarks/paper_n5/exp1.json \
    --config benchmarks/paper_n5/exp2.json --seeds "$SEEDS" \
    --results "$RESULTS" --workers "$WORKERS" --threads 1 --quiet
