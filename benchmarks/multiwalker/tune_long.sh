#!/usr/bin/env bash
# Issue 57, item 2, step 1b: multiwalker's tuning at a budget where another library saw it learn. The first stage
# (tune.sh: 16 trials of 150,000 steps) found no setting that keeps the walkers up. Mava's MAD4PG learned multiwalker
# to a return of about 40 in about 1M env steps with learning rate 1e-4, exploration noise 0.3, one network shared by
# the walkers, batch 1024 and discount 0.99 (instadeepai/Mava issue 314, 2021). This stage tunes the rest (network width,
# update ratio, tau, the actor regulariser) with those held, at 1,000,000 steps a trial, objective package_distance,
# 5 evaluations of 5 episodes. That the first stage's budget was too short is the hypothesis it tests.
#
# Run it from a worktree pinned to a commit, writing into the main checkout; it resumes (the study is in SQLite):
#   git worktree add --detach ../sweep-multiwalker <commit>
#   cd ../sweep-multiwalker && OUT=/work/main/benchmarks/multiwalker TRIALS=2 nohup bash benchmarks/multiwalker/tune_long.sh &
set -u
cd "$(dirname "$0")/../.."
OUT="${OUT:-benchmarks/multiwalker}"
TRIALS="${TRIALS:-2}"  # finished trials to reach: about 1.2-2 core-hours each
export SDL_VIDEODRIVER=dummy
echo "$(date -u +%FT%TZ) commit $(git rev-parse HEAD) tune_long multiwalker trials $TRIALS" >>"$OUT/commits.log"
FIXED='{"learning_rate": 0.0001, "noise_std": 0.3, "batch_size": 1024, "gamma": 0.99}'
MODEL='{"buffer_size": 1000000, "policy_kwargs": {"share_parameters": true}}'
for finished in $(seq 1 "$TRIALS"); do  # one process per trial, its CPU time in cpu_time.log
  nice -n 19 /usr/bin/time -a -o "$OUT/cpu_time.log" -f "started $(date -u +%FT%TZ) long trials<=$finished wall_s %e user_s %U sys_s %S" \
      python -m sb3_maddpg tune --config multiwalker --scheme full --storage "sqlite:///$OUT/tune.db" \
      --study-name multiwalker_full_1m --n-trials "$finished" --budget 1000000 --n-evaluations 5 --eval-episodes 5 \
      --warmup-evaluations 2 --seed 0 --workers 1 --threads 1 --fixed-params "$FIXED" --model-kwargs "$MODEL" \
      --preset-out "$OUT/best_1m.yml" || exit $?
done
