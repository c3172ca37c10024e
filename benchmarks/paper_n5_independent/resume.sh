#!/usr/bin/env bash
# Issue 56's background runs, resumed in one command at a session's start (the runs end with each session), one core
# a lane, each from a worktree at the commit its runs started from (created where missing):
#
#   lane 1, Exp. 1 seeds 5-9 (424c90c): run.sh with SETTINGS=exp1 and SEEDS 0-9 (a narrower list would rewrite
#           experiment.json's seeds), then the fixed graph if it is not running or done;
#   lane 2, Exp. 2's three missing schemes into results_exp2_extra/ (487a75a), then the same.
#   The fixed graph (item 4): Exp. 1's selected over a fixed ring of partners into results_fixed_graph/, from 487a75a,
#   which reads its {"neighbors": ...} selector; whichever lane comes to it second finds it running (its lock) or done.
#   Once Exp. 1's 60 runs are done and Exp. 2's three merged, one lane runs the fixed graph on both cores (2 workers).
#
# First, if all 15 runs of Exp. 2's three have finished and are not merged yet, it merges them into results/
# (merge_exp2_extra.sh, which needs results/'s lock: free before lane 1 starts). Finished runs are skipped and a killed
# run goes on from its last snapshot. While a sweep runs in one of the three results folders it starts nothing.
# A snapshot (resume/, not committed: a replay buffer) lives on its disk only: in a new checkout such a run starts
# again from zero.
#
#     bash benchmarks/paper_n5_independent/resume.sh            # from the main checkout
#     DRY_RUN=1 bash benchmarks/paper_n5_independent/resume.sh  # only say what it would do
#     STOP_AFTER=06:20 bash benchmarks/paper_n5_independent/resume.sh
#
# STOP_AFTER (a time `date -d` reads, UTC): once it has passed, each lane ends as soon as one more of its runs finishes,
# before the next one trains (it is sent SIGTERM seconds into that run), and does not go on to the fixed graph: set it
# to the session's end less a run's length (about 45 minutes), so that no run is cut off there. The fixed graph on two
# workers ends once two runs have finished after that time (the second worker's, and the first worker's next run,
# cut back to its last snapshot: a new checkout starts it again).
# Logs: /tmp/sweep-n5i.log (lane 1), /tmp/sweep-side.log (lane 2), /tmp/sweep-fixed.log (the fixed graph alone).
set -euo pipefail
STUDY="$(cd "$(dirname "$0")" && pwd)"
MAIN="$(cd "$STUDY/../.." && pwd)"
EXP1_TREE="$(dirname "$MAIN")/sweep-n5i-seeds5-9" EXP1_COMMIT=424c90c185500c638bd4ee2e386b39b30745b4f1
SIDE_TREE="$(dirname "$MAIN")/sweep-n5i-queued" SIDE_COMMIT=487a75a81eef8aa399c4c25e39a13055cfbcfa8c
FIXED="$STUDY/results_fixed_graph"
export SDL_VIDEODRIVER=dummy

now() { date -u +%Y-%m-%dT%H:%M:%SZ; }
STOP_AFTER="${STOP_AFTER:-}"
if [ -n "$STOP_AFTER" ]; then
    STOP_AT="$(date -u -d "$STOP_AFTER" +%s)" || { echo "STOP_AFTER=$STOP_AFTER is no time date -d reads" >&2; exit 2; }
fi
# a snapshot's rename can make find fail on a folder it walks: that must not end the watcher under set -e
runs_done() { { find "$1" -path '*/seed_*/done' 2> /dev/null || true; } | wc -l; }

watched() {  # watched RESULTS LANE CMD...: CMD, stopped past STOP_AFTER once STOP_RUNS more runs under RESULTS finished
    local results="$1" stopped="/tmp/sweep-$2.stopped" pid before
    shift 2
    rm -f "$stopped"
    "$@" &
    pid=$!
    if [ -n "$STOP_AFTER" ]; then
        (
            before="$(runs_done "$results")"
            while kill -0 "$pid" 2> /dev/null; do
                done_now="$(runs_done "$results")"
                if [ "$(date -u +%s)" -lt "$STOP_AT" ]; then
                    before="$done_now"  # a run finished before STOP_AFTER does not count
                elif [ "$((done_now - before))" -ge "${STOP_RUNS:-1}" ]; then
                    echo "$(now) past STOP_AFTER=$STOP_AFTER and ${STOP_RUNS:-1} run(s) have finished since: stopping"
                    touch "$stopped"
                    # SIGTERM: a sweep started in the background ignores SIGINT (as bash starts it); seconds into its
                    # next run there is no snapshot to lose
                    if [ "$(ps -o comm= -p "$pid")" = bash ]; then  # the sweep under run.sh's shell, not a pool's workers
                        pkill -TERM -P "$pid" || true
                    fi
                    kill -TERM "$pid" 2> /dev/null || true
                    break
                fi
                sleep 10
            done
        ) &
    fi
    wait "$pid" || [ -f "$stopped" ]  # a sweep stopped on purpose is no failure
}
stopped() { [ -f "/tmp/sweep-$1.stopped" ]; }
locked() { [ -f "$1/sweep.lock" ] && ! flock -n "$1/sweep.lock" true; }  # a sweep there holds the lock
finished() { # finished() DIR EXPERIMENT SCHEME...: every one of those schemes has seeds 0-4 done under DIR
    local results="$1" experiment="$2" scheme seed
    shift 2
    for scheme in "$@"; do
        for seed in 0 1 2 3 4; do
            [ -f "$results/$experiment/$scheme/seed_00$seed/done" ] || return 1
        done
    done
}

fixed_graph() {  # fixed_graph LANE WORKERS: unless it runs in the other lane already or is done, or STOP_AFTER passed
    cd "$SIDE_TREE"
    if [ -n "$STOP_AFTER" ] && [ "$(date -u +%s)" -ge "$STOP_AT" ]; then
        echo "$(now) past STOP_AFTER=$STOP_AFTER: the fixed graph is not started"
        return 0
    fi
    if finished "$FIXED" paper_n5i_exp1_fixed_graph selected_fixed; then
        echo "the fixed graph's 5 runs are done"
        return 0
    fi
    mkdir -p "$FIXED"
    if locked "$FIXED"; then
        echo "the fixed graph runs in the other lane"
        return 0
    fi
    echo "$(now) commit $SIDE_COMMIT item 4: exp1_fixed_graph seeds 0-4 workers $2" >> "$FIXED/commits.log"
    watched "$FIXED" "$1" nice -n 19 python -m sb3_maddpg run \
        --config benchmarks/paper_n5_independent/exp1_fixed_graph.json \
        --seeds 0,1,2,3,4 --results "$FIXED" --workers "$2" --threads 1 --quiet
}

case "${1:-}" in
    --lane1)
        cd "$EXP1_TREE"
        SETTINGS=exp1 SEEDS=0,1,2,3,4,5,6,7,8,9 RESULTS_ROOT="$MAIN/benchmarks" WORKERS=1 \
            watched "$STUDY/results" lane1 bash benchmarks/paper_n5_independent/run.sh
        stopped lane1 || fixed_graph lane1 1
        exit 0
        ;;
    --lane2)
        cd "$SIDE_TREE"
        if [ "${2:-}" != merged ]; then
            echo "$(now) commit $SIDE_COMMIT side queue resumed: exp2 independent,observations,actions seeds 0-4" \
                >> "$STUDY/results_exp2_extra/commits.log"
            watched "$STUDY/results_exp2_extra" lane2 nice -n 19 python -m sb3_maddpg run \
                --config benchmarks/paper_n5_independent/exp2.json \
                --schemes "[independent,observations,actions]" --seeds 0,1,2,3,4 \
                --results "$STUDY/results_exp2_extra" --workers 1 --threads 1 --quiet
        fi
        stopped lane2 || fixed_graph lane2 1
        exit 0
        ;;
    --fixed)
        STOP_RUNS=2 fixed_graph fixed 2  # one run per worker past STOP_AFTER
        exit 0
        ;;
    "") ;;
    *)
        echo "resume.sh takes no argument (--lane1, --lane2 and --fixed are its own lanes): run it as it is" >&2
        exit 2
        ;;
esac

DRY_RUN="${DRY_RUN:-}"
for results in "$STUDY/results" "$STUDY/results_exp2_extra" "$FIXED"; do
    if locked "$results"; then
        echo "a sweep runs in $results already ($(cat "$results/sweep.lock")): this starts lanes only when none" \
            "runs; stop them (kill <pid>, right after a run's train.log says \"snapshot at\": they resume from it) or" \
            "let them go on" >&2
        [ -n "$DRY_RUN" ] || exit 1
    fi
done

for tree_commit in "$EXP1_TREE $EXP1_COMMIT" "$SIDE_TREE $SIDE_COMMIT"; do
    read -r tree commit <<< "$tree_commit"
    if [ ! -d "$tree" ]; then
        if [ -n "$DRY_RUN" ]; then echo "would create the worktree $tree at $commit"; continue; fi
        git -C "$MAIN" worktree add --detach "$tree" "$commit"
    fi
    if [ "$(git -C "$tree" rev-parse HEAD)" != "$commit" ]; then
        echo "$tree is not at $commit: its runs must come from the commit they started from" >&2
        exit 1
    fi
done

merged="$(python -c 'import json, sys; print("independent" in json.load(open(sys.argv[1]))["schemes"])' \
    "$STUDY/results/paper_n5i_exp2/experiment.json")"
if [ "$merged" = False ] && finished "$STUDY/results_exp2_extra" paper_n5i_exp2 independent observations actions; then
    if [ -n "$DRY_RUN" ]; then
        echo "would merge Exp. 2's three (merge_exp2_extra.sh)"
    elif bash "$STUDY/merge_exp2_extra.sh"; then
        merged=True
    else
        echo "the merge failed (above); the lanes start all the same and it is tried again at the next start" >&2
    fi
fi
if [ "$merged" = True ] && [ "$(runs_done "$STUDY/results/paper_n5i_exp1")" -ge 60 ]; then
    if finished "$FIXED" paper_n5i_exp1_fixed_graph selected_fixed; then
        echo "nothing to resume: Exp. 1, Exp. 2 and the fixed graph are done"
        exit 0
    fi
    if [ -n "$DRY_RUN" ]; then
        echo "Exp. 1's 60 runs are done and Exp. 2's three merged: would run the fixed graph on both cores"
        [ -z "$STOP_AFTER" ] || echo "it would end once two runs have finished after $(date -u -d "@$STOP_AT")"
        exit 0
    fi
    rm -f /tmp/sweep-fixed.stopped
    nohup bash "$STUDY/resume.sh" --fixed > /tmp/sweep-fixed.log 2>&1 &
    echo "started the fixed graph on both cores (/tmp/sweep-fixed.log): Exp. 1 and Exp. 2 are done"
    exit 0
fi
lane2="Exp. 2's three, then the fixed graph"
[ "$merged" = True ] && lane2="the fixed graph (Exp. 2's three are merged)"
if [ -n "$DRY_RUN" ]; then
    echo "would start lane 1 (Exp. 1 seeds 0-9 from $EXP1_TREE, then the fixed graph) and lane 2 ($lane2)"
    [ -z "$STOP_AFTER" ] || echo "each lane would end at the first run it finishes after $(date -u -d "@$STOP_AT")"
    exit 0
fi
rm -f /tmp/sweep-lane1.stopped /tmp/sweep-lane2.stopped  # a lane's mark from an earlier start
nohup bash "$STUDY/resume.sh" --lane1 > /tmp/sweep-n5i.log 2>&1 &
nohup bash "$STUDY/resume.sh" --lane2 "$([ "$merged" = True ] && echo merged || echo extra)" > /tmp/sweep-side.log 2>&1 &
echo "started lane 1 (Exp. 1, then the fixed graph; /tmp/sweep-n5i.log) and lane 2 ($lane2; /tmp/sweep-side.log)"
