#!/usr/bin/env bash
# Issue 21's target at N=5 (exp1 setting: full observability, `full` sharing, 3 seeds within the paper's 2.5M env
# steps): the candidate configuration of the diagnosis, agents and landmarks observed nearest first, one gradient
# step per 25 transitions, one actor and one critic shared by all agents; then the same at the paper's one step per 100
# transitions (3 seeds): what the paper's 25,000 gradient steps allow; then (2026-12-03) the first with the tuning
# study's best trial (benchmarks/n5_tuning: learning rate 7.7e-4, noise 0.098, tau 0.02, gamma 0.9), ahead early and
# level at 1M steps in benchmarks/n5_diagnosis; ahead at 2.5M, it is now the exp1 entry (exp1_tuned).
# Resumable: run it again and finished runs are skipped. Usage: WORKERS=3 bash benchmarks/n5_tuned/run.sh
# Then: python benchmarks/n5_tuned/summarize.py (and python benchmarks/n5_tuned/plot.py for the docs' figure)
set -u
cd "$(dirname "$0")/../.."
RESULTS_ROOT="${RESULTS_ROOT:-benchmarks}"
WORKERS="${WORKERS:-3}"
export SDL_VIDEODRIVER=dummy
nice -n 19 python -m sb3_maddpg run --config benchmarks/n5_tuned/exp1_shared.json \
    --config benchmarks/n5_tuned/exp1_shared_tpu100.json --config benchmarks/n5_tuned/exp1_shared_best.json \
    --results "$RESULTS_ROOT/n5_tuned/results" --workers "$WORKERS" --threads 1 --quiet
