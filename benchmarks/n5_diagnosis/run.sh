#!/usr/bin/env bash
# Issue 21's diagnosis at N=5 (exp1 setting: full observability, `full` sharing, batched env with 100 worlds):
# each factor against the paper's configuration in one sweep, 3 seeds x 1M steps, configs in priority order
# (four gradient steps per 100 transitions moved ahead on 2026-12-02: learning followed gradient steps, not env steps;
# then, the same day, one-seed probes on the best of them, nearest-first with one step per 25 transitions, ahead of the
# paper-based factors still to finish: their configs list seed 0 only until one leads; and then, when nearest-first
# observations with a shared actor and critic led by far (0.92-1.02 at 350k steps, seed 0), probes on that first,
# then the paper-based factors the issue lists: noise, observation normalisation, layer normalisation, width, one
# step per 10 transitions; on 2026-12-02 (later) the paper-based factors at 3 seeds moved ahead of the shared probes:
# the shared configuration already has 3 seeds at 2.5M in benchmarks/n5_tuned; on 2026-12-02, the paper's
# configuration at one step per 25 transitions (3 seeds) moved ahead of the probes, and one step per 10 transitions left
# this queue: `n5_tpu10_maddpg` in benchmarks/matd3 is that configuration at 200k steps, 3 seeds;
# summarize.py reads it); on 2026-12-03 the tuning study's best trial (benchmarks/n5_tuning) moved to the front, beside
# the shared configuration's seeds 1 and 2 it is measured against.
# Resumable: run it again and finished runs are skipped. Usage: bash benchmarks/n5_diagnosis/run.sh
# Then: python benchmarks/n5_diagnosis/summarize.py
set -u
cd "$(dirname "$0")/../.."
RESULTS_ROOT="${RESULTS_ROOT:-benchmarks}"
WORKERS="${WORKERS:-2}"
export SDL_VIDEODRIVER=dummy
configs=()
for factor in sorted_obs_utd25_shared_params_tuned sorted_obs_utd25_shared_params \
    paper sorted_obs utd400 lr1e-3 sorted_obs_utd25 sorted_obs_batch256_utd25 \
    noise0.3 obs_norm layer_norm batch256 width128 shared_params utd25 \
    sorted_obs_utd25_shared_params_matd3 sorted_obs_utd25_shared_params_layer_norm \
    sorted_obs_utd25_shared_params_lr1e-3 sorted_obs_utd10_shared_params \
    sorted_obs_utd25_matd3 sorted_obs_utd25_layer_norm sorted_obs_batch256_utd10 sorted_obs_utd25_lr1e-3; do
    configs+=(--config "benchmarks/n5_diagnosis/$factor.json")
done
nice -n 19 python -m sb3_maddpg run "${configs[@]}" --results "$RESULTS_ROOT/n5_diagnosis/results" \
    --workers "$WORKERS" --threads 1 --quiet
