#!/usr/bin/env bash
# Issue 10's measurements: discrete against continuous simple_spread (N=3, full sharing, 3 seeds, 300k steps,
# learning-curve evaluations of 100 episodes at 0, 100k, 200k and 300k steps), and short learning runs on
# speaker-listener and simple_tag (100k steps, 3 seeds). Resumable. Usage: bash benchmarks/discrete_and_tasks/run.sh
set -u
cd "$(dirname "$0")/../.."
RESULTS_ROOT="${RESULTS_ROOT:-benchmarks}"
WORKERS="${WORKERS:-1}"
export SDL_VIDEODRIVER=dummy
configs=()
for name in spread_continuous spread_discrete speaker_listener tag; do
    configs+=(--config "benchmarks/discrete_and_tasks/$name.json")
done
nice -n 19 python -m sb3_maddpg run "${configs[@]}" --results "$RESULTS_ROOT/discrete_and_tasks/results" \
    --workers "$WORKERS" --threads 1 --quiet
