#!/usr/bin/env bash
# Issue 57, item 1: SISL pursuit through sb3-maddpg run, the preset `pursuit` (Beyond MPE's setting: the six schemes x
# 5 seeds, 200k env steps each, random actions and doing nothing evaluated beside them on the same episodes).
#
# Run it from a worktree pinned to a commit, writing results into the main checkout:
#   git worktree add --detach ../sweep-pursuit <commit>
#   cd ../sweep-pursuit && RESULTS_ROOT=/work/main/benchmarks WORKERS=2 nohup bash benchmarks/pursuit/run.sh &
# Resumable: run it again and finished runs are skipped, as are the reference policies' seeds already evaluated; a run
# killed midway starts again from scratch (pursuit's envs cannot be snapshotted). Each start appends its commit to
# results/commits.log; each run's config.json names it too. SEEDS (default 0,1,2,3,4, comma-separated) runs others.
set -u
cd "$(dirname "$0")/../.."
RESULTS_ROOT="${RESULTS_ROOT:-benchmarks}"
WORKERS="${WORKERS:-2}"
SEEDS="${SEEDS:-0,1,2,3,4}"
RESULTS="$RESULTS_ROOT/pursuit/results"
export SDL_VIDEODRIVER=dummy
python -c "import pettingzoo.sisl.pursuit_v5" 2>/dev/null || {
  echo "pursuit needs PettingZoo's SISL envs: install the sisl extra, pip install -e '.[sisl]'" >&2
  exit 2
}
mkdir -p "$RESULTS"
echo "$(date -u +%FT%TZ) commit $(git rev-parse HEAD) study pursuit seeds $SEEDS workers $WORKERS" >>"$RESULTS/commits.log"
nice -n 19 python -m sb3_maddpg run --config pursuit --seeds "[$SEEDS]" \
    --results "$RESULTS" --workers "$WORKERS" --threads 1 --quiet
