#!/usr/bin/env bash
# Issue 57, item 2, step 1: find multiwalker's training settings with the package's own tuning (Optuna), on a small
# budget: TRIALS (16 by default) trials of 150,000 env steps, `full` sharing, seed 0, objective package_distance (how
# far the walkers carry the package), 5 evaluations of 5 episodes per trial, the median pruner past the first 2.
#
# Run it from a worktree pinned to a commit, writing into the main checkout; it resumes (the study is in SQLite):
#   git worktree add --detach ../sweep-multiwalker <commit>
#   cd ../sweep-multiwalker && OUT=/work/main/benchmarks/multiwalker WORKERS=1 nohup bash benchmarks/multiwalker/tune.sh &
# Then: the best trial's values go into sb3_maddpg/experiments/presets/multiwalker.yml (its model_kwargs), stated there
# with the study's numbers; `sb3-maddpg tune ... --preset-out` writes them as a preset file to copy from.
set -u
cd "$(dirname "$0")/../.."
OUT="${OUT:-benchmarks/multiwalker}"
WORKERS="${WORKERS:-1}"
TRIALS="${TRIALS:-16}"  # the study's finished trials to reach (the stop rule is about 6 core-hours in all)
export SDL_VIDEODRIVER=dummy
echo "$(date -u +%FT%TZ) commit $(git rev-parse HEAD) tune multiwalker workers $WORKERS trials $TRIALS" >>"$OUT/commits.log"
# One process per trial: in one process a worker's memory grew to 21 GB over six multiwalker trials (2026-12-06, not
# yet explained), which starved the runs beside it. The study resumes from its SQLite file at each call.
# Each trial process's CPU time is appended to cpu_time.log, so the core-hours spent are measured, not estimated.
for finished in $(seq 1 "$TRIALS"); do
  nice -n 19 /usr/bin/time -a -o "$OUT/cpu_time.log" -f "started $(date -u +%FT%TZ) trials<=$finished wall_s %e user_s %U sys_s %S" \
      python -m sb3_maddpg tune --config multiwalker --scheme full --storage "sqlite:///$OUT/tune.db" \
      --study-name multiwalker_full --n-trials "$finished" --budget 150000 --n-evaluations 5 --eval-episodes 5 \
      --warmup-evaluations 2 --seed 0 --workers "$WORKERS" --threads 1 --preset-out "$OUT/best.yml" || exit $?
done
