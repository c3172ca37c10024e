#!/usr/bin/env bash
# The study's report from the committed runs (issue 31): the seeds every scheme of a setting has finished, written into
# docs/_static/paper_n5 over the last one (its README.md, the hand-written reading, stays). Run it from the repository
# root in the commit that adds runs completing a seed of every scheme:
# tests/experiments/test_experiments.py::test_report_regenerates_the_committed_results fails on a stale report.
set -euo pipefail
cd "$(dirname "$0")/../.."
export SDL_VIDEODRIVER=dummy
python -m sb3_maddpg report benchmarks/paper_n5/results --complete-seeds --out docs/_static/paper_n5 \
    --metric success_rate_r0.3 --metric success_rate --metric min_dist_sum --metric return_mean
rm -f docs/_static/paper_n5/marl_eval.json  # marl-eval's input, not shown in the docs
