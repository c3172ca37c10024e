#!/usr/bin/env bash
# Issue 56, item 3: move Exp. 2's three schemes run beside the Exp. 1 sweep (results_exp2_extra/, from 487a75a) into
# the study's results/paper_n5i_exp2/ once all 15 runs have finished, so that the report's Exp. 2 pages go from three
# schemes at seeds 0-4 to six at seeds 0-4, never through a partial seed set. The package's sweep then checks that the
# moved runs belong (a finished run with another config is an error) and writes the six schemes into experiment.json:
# the report declares each family from that stored list. It needs results/'s lock: stop the Exp. 1 sweep first (it
# resumes from its last snapshot). Then run report.sh and commit.
#
#     bash benchmarks/paper_n5_independent/merge_exp2_extra.sh
#
# STUDY names another copy of this folder (for a trial run of the script).
set -euo pipefail
STUDY="${STUDY:-$(cd "$(dirname "$0")" && pwd)}"
EXTRA="$STUDY/results_exp2_extra/paper_n5i_exp2"
TARGET="$STUDY/results/paper_n5i_exp2"
SCHEMES=(independent observations actions)
CONFIG="$(cd "$(dirname "$0")" && pwd)/exp2.json"

if [ -f "$STUDY/results/sweep.lock" ] && ! flock -n "$STUDY/results/sweep.lock" true; then
    echo "a sweep runs in results/ ($(cat "$STUDY/results/sweep.lock")): stop it first (kill <pid>, right after a run's" \
        "train.log says \"snapshot at\": it resumes from that snapshot), then merge" >&2
    exit 1
fi
for scheme in "${SCHEMES[@]}"; do
    if [ -e "$TARGET/$scheme" ]; then
        echo "$TARGET/$scheme exists already: the merge has run, or a run of that scheme is in the way" >&2
        exit 1
    fi
    for seed in 0 1 2 3 4; do
        run="$EXTRA/$scheme/seed_00$seed"
        if [ ! -f "$run/done" ]; then
            echo "$run has not finished: resume the Exp. 2 side queue (README, Step 2) and merge when all 15 are done" >&2
            exit 1
        fi
    done
done

moved=()
move_back() {  # until the sweep has written the six schemes into experiment.json, any failure undoes the moves
    for scheme in "${moved[@]}"; do
        mv "$TARGET/$scheme" "$EXTRA/$scheme"
    done
    echo "not merged, the runs are back in results_exp2_extra/" >&2
}
trap move_back EXIT
for scheme in "${SCHEMES[@]}"; do
    mv "$EXTRA/$scheme" "$TARGET/$scheme"
    moved+=("$scheme")
done
# Nothing may be left to train: a run the check does not count as finished would otherwise start here.
plan="$(SDL_VIDEODRIVER=dummy python -m sb3_maddpg run --config "$CONFIG" --results "$STUDY/results" \
    --seeds 0,1,2,3,4 --dry-run 2>&1 | tail -n 1)" || plan="the check failed: $plan"
if [ "$plan" != "0 run(s) to do, 30 finished" ]; then
    echo "the sweep's check says '$plan' (its whole message: move the runs in again and run sb3-maddpg run --config" \
        "$CONFIG --results $STUDY/results --seeds 0,1,2,3,4 --dry-run)" >&2
    exit 1
fi
SDL_VIDEODRIVER=dummy python -m sb3_maddpg run --config "$CONFIG" --results "$STUDY/results" --seeds 0,1,2,3,4 \
    --workers 1 --threads 1 --quiet
trap - EXIT
echo "$(date -u +%Y-%m-%dT%H:%M:%SZ) merged exp2 independent,observations,actions seeds 0-4 from" \
    "results_exp2_extra/ (run from 487a75a: its commits.log)" >> "$STUDY/results/commits.log"
echo "merged: results/paper_n5i_exp2 holds six schemes at seeds 0-4; now run report.sh. The README's table gains" \
    "two Exp. 2 rows (about 60 words; tried on a copy: 964 -> 1,026): trim its prose to keep README.md within its 1,000" \
    "(tests/test_docs_length.py)"
