#!/usr/bin/env bash
# Issue 56's background runs, resumed in one command at a session's start (the runs end with each session), one core
# each, from worktrees pinned to the commits they started from (created where missing):
#
#   lane 1, Exp. 1 seeds 5-9 (424c90c): run.sh with SETTINGS=exp1 and SEEDS 0-9 (a narrower list would rewrite
#           experiment.json's seeds), then the fixed graph below if lane 2 has not started it;
#   lane 2, from 487a75a: Exp. 2's three missing schemes into results_exp2_extra/, then, when all 15 have finished,
#           Exp. 1's selected over a fixed neighbour graph into results_fixed_graph/ (item 4).
#
# Before either starts, Exp. 2's three are merged into results/ if all 15 have finished and they are not merged yet
# (merge_exp2_extra.sh; it needs results/'s lock, free before lane 1 starts). Finished runs are skipped, a killed run
# goes on from its last snapshot; while a sweep runs in one of the three results folders (its lock) it starts nothing.
#
#     bash benchmarks/paper_n5_independent/resume.sh          # from the main checkout
#     DRY_RUN=1 bash benchmarks/paper_n5_independent/resume.sh  # only say what it would start
#
# Logs: /tmp/sweep-n5i.log (lane 1), /tmp/sweep-side.log (lane 2).
set -euo pipefail
STUDY="$(cd "$(dirname "$0")" && pwd)"
MAIN="$(cd "$STUDY/../.." && pwd)"
EXP1_TREE="$MAIN/../sweep-n5i-seeds5-9" EXP1_COMMIT=424c90c185500c638bd4ee2e386b39b30745b4f1
SIDE_TREE="$MAIN/../sweep-n5i-queued" SIDE_COMMIT=487a75a81eef8aa399c4c25e39a13055cfbcfa8c
DRY_RUN="${DRY_RUN:-}"

worktree() {  # a worktree at its commit, or a refusal that says why
    local tree="$1" commit="$2"
    if [ ! -d "$tree" ]; then
        if [ -n "$DRY_RUN" ]; then echo "would create the worktree $tree at $commit"; return; fi
        git -C "$MAIN" worktree add --detach "$tree" "$commit"
    fi
    if [ "$(git -C "$tree" rev-parse HEAD)" != "$commit" ]; then
        echo "$tree is not at $commit: its runs must come from the commit they started from" >&2
        exit 1
    fi
}
for results in results results_exp2_extra results_fixed_graph; do  # a running sweep holds its results' lock
    if [ -f "$STUDY/$results/sweep.lock" ] && ! flock -n "$STUDY/$results/sweep.lock" true; then
        echo "a sweep is running in $results/ already ($(cat "$STUDY/$results/sweep.lock")): this starts lanes only" \
            "when none runs; stop them (kill -INT, they resume from their snapshots) or let them go on" >&2
        exit 1
    fi
done
worktree "$EXP1_TREE" "$EXP1_COMMIT"
worktree "$SIDE_TREE" "$SIDE_COMMIT"

extras_done=1
for scheme in independent observations actions; do
    for seed in 0 1 2 3 4; do
        [ -f "$STUDY/results/paper_n5i_exp2/$scheme/seed_00$seed/done" ] ||
            [ -f "$STUDY/results_exp2_extra/paper_n5i_exp2/$scheme/seed_00$seed/done" ] || extras_done=0
    done
done
merged=0
[ -d "$STUDY/results/paper_n5i_exp2/independent" ] && merged=1
if [ "$extras_done" = 1 ] && [ "$merged" = 0 ]; then
    if [ -n "$DRY_RUN" ]; then echo "would merge Exp. 2's three (merge_exp2_extra.sh)"; else bash "$STUDY/merge_exp2_extra.sh"; fi
    merged=1
fi

now() { date -u +%Y-%m-%dT%H:%M:%SZ; }
EXP2_EXTRA="SDL_VIDEODRIVER=dummy nice -n 19 python -m sb3_maddpg run --config benchmarks/paper_n5_independent/exp2.json \
--schemes '[independent,observations,actions]' --seeds 0,1,2,3,4 --results $STUDY/results_exp2_extra --workers 1 \
--threads 1 --quiet"
FIXED="$STUDY/results_fixed_graph"  # from lane 2's worktree, the commit that reads its {"neighbors": ...} selector
FIXED_GRAPH="cd $SIDE_TREE && mkdir -p $FIXED && flock -n $FIXED/sweep.lock true && echo \"\$(date -u +%Y-%m-%dT%H:%M:%SZ) \
commit $SIDE_COMMIT item 4: exp1_fixed_graph seeds 0-4\" >> $FIXED/commits.log && SDL_VIDEODRIVER=dummy nice -n 19 \
python -m sb3_maddpg run --config benchmarks/paper_n5_independent/exp1_fixed_graph.json --seeds 0,1,2,3,4 --results \
$FIXED --workers 1 --threads 1 --quiet"
if [ "$merged" = 1 ]; then
    side="$FIXED_GRAPH"
else
    side="echo \"$(now) commit $SIDE_COMMIT side queue resumed: exp2 independent,observations,actions seeds 0-4\" >> \
$STUDY/results_exp2_extra/commits.log && $EXP2_EXTRA && $FIXED_GRAPH"
fi
# Lane 1 takes the fixed graph when Exp. 1 is done and lane 2 has not (flock: a sweep there holds its lock; then none).
lane1="SETTINGS=exp1 SEEDS=0,1,2,3,4,5,6,7,8,9 RESULTS_ROOT=$MAIN/benchmarks WORKERS=1 bash benchmarks/paper_n5_independent/run.sh \
&& $FIXED_GRAPH"

if [ -n "$DRY_RUN" ]; then
    printf 'lane 1, in %s:\n  %s\nlane 2, in %s:\n  %s\n' "$EXP1_TREE" "$lane1" "$SIDE_TREE" "$side"
    exit 0
fi
(cd "$EXP1_TREE" && nohup bash -c "$lane1" > /tmp/sweep-n5i.log 2>&1 &)
(cd "$SIDE_TREE" && nohup bash -c "$side" > /tmp/sweep-side.log 2>&1 &)
echo "started: lane 1 (Exp. 1, log /tmp/sweep-n5i.log) and lane 2 ($([ "$merged" = 1 ] && echo "the fixed graph" ||
    echo "Exp. 2's three, then the fixed graph"), log /tmp/sweep-side.log)"
