#!/usr/bin/env bash
# The N=3 study and then the N=5 outlook (issue 13), in the background and resumable: run the same command
# again and finished runs are skipped, an interrupted run starts over.
#   bash benchmarks/paper_n3/run_study.sh                  # results under benchmarks/ of this checkout
#   RESULTS_ROOT=/path/to/checkout/benchmarks bash ...     # run a frozen copy of the code, results elsewhere
set -u
cd "$(dirname "$0")/../.."
RESULTS_ROOT="${RESULTS_ROOT:-benchmarks}"
WORKERS="${WORKERS:-2}"
export SDL_VIDEODRIVER=dummy
nice -n 19 python -m sb3_maddpg run --config n3_full --config n3_partial \
    --results "$RESULTS_ROOT/paper_n3/results" --workers "$WORKERS" --threads 1 --quiet
nice -n 19 python -m sb3_maddpg run --config exp1 --name n5_outlook --schemes full,selected --seeds 3 \
    --no-keep-checkpoints --results "$RESULTS_ROOT/paper_n5_outlook/results" --workers "$WORKERS" --threads 1 --quiet
