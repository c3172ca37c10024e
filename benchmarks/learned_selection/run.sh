#!/usr/bin/env bash
# Issue 12's measurement: full, selected (k nearest), attention and learned_selection (same k) on simple_spread,
# N=3 (k=1) and N=5 (k=2), full observability, 5 seeds x 1M steps, the paper's hyperparameters on the batched env.
# Resumable: run it again and finished runs are skipped. Usage: bash benchmarks/learned_selection/run.sh
set -u
cd "$(dirname "$0")/../.."
RESULTS_ROOT="${RESULTS_ROOT:-benchmarks}"
WORKERS="${WORKERS:-2}"
export SDL_VIDEODRIVER=dummy
nice -n 19 python -m sb3_maddpg run --config benchmarks/learned_selection/n3.json \
    --config benchmarks/learned_selection/n5.json --results "$RESULTS_ROOT/learned_selection/results" \
    --workers "$WORKERS" --threads 1 --quiet
