#!/usr/bin/env bash
# Issue 21's target at N=5 (exp1 setting: full observability, `full` sharing, 3 seeds within the paper's 2.5M env
# steps): the candidate configuration of the diagnosis, agents and landmarks observed nearest first, one gradient
# step per 25 transitions, one actor and one critic shared by all agents; then the same at the paper's one step per 100
# transitions (3 seeds): what the paper's 25,000 gradient steps allow.
# Resumable: run it again and finished runs are skipped. Usage: WORKERS=3 bash benchmarks/n5_tuned/run.sh
# Then: python -m sb3_maddpg.experiments report benchmarks/n5_tuned/results --metric min_dist_sum --metric success_rate_r0.3
set -u
cd "$(dirname "$0")/../.."
RESULTS_ROOT="${RESULTS_ROOT:-benchmarks}"
WORKERS="${WORKERS:-3}"
export SDL_VIDEODRIVER=dummy
nice -n 19 python -m sb3_maddpg.experiments run --config benchmarks/n5_tuned/exp1_shared.json \
    --config benchmarks/n5_tuned/exp1_shared_tpu100.json \
    --results "$RESULTS_ROOT/n5_tuned/results" --workers "$WORKERS" --threads 1 --quiet
