#!/usr/bin/env bash
# Issue 22: MATD3 against MADDPG in one sweep: N=3 and N=5 (exp1's setting, full observability), `full` and `selected`,
# 3 seeds x 1M steps, learning curves and final scores; then N=5 with one gradient step per 10 transitions.
# Each algorithm is its own experiment (n5_matd3, n5_maddpg, ...), so that `report` gives each its own rows.
# Resumable: run it again and finished runs are skipped (an interrupted run starts over).
#   bash benchmarks/matd3/run.sh                       # results under benchmarks/matd3/results
#   RESULTS_ROOT=/elsewhere WORKERS=4 bash benchmarks/matd3/run.sh
# Then: python -m sb3_maddpg report benchmarks/matd3/results
set -u
cd "$(dirname "$0")/../.."
RESULTS_ROOT="${RESULTS_ROOT:-benchmarks}"
WORKERS="${WORKERS:-2}"
export SDL_VIDEODRIVER=dummy
configs=()
# Priority order: N=3 (the cheapest: about 1 core-hour), then the N=5 comparison, then the costly
# 10-transitions-per-step pair (10x the gradient steps).
for name in n3_maddpg n3_matd3 n5_maddpg n5_matd3 n5_tpu10_maddpg n5_tpu10_matd3; do
    configs+=(--config "benchmarks/matd3/$name.json")
done
nice -n 19 python -m sb3_maddpg run "${configs[@]}" --results "$RESULTS_ROOT/matd3/results" \
    --workers "$WORKERS" --threads 1 --quiet
