#!/usr/bin/env bash
# Issue 31's device check, one call on a lent GPU (run by the device tool from the repository root; $OUT comes back):
# the CUDA tests, then the study's exp1 preset as a run group of the paper's 31 seeds on the GPU (`--backend batched
# --device cuda`), at a shortened budget, to measure what the paper's protocol would cost there.
#   EPISODES (default 4000: 100k env steps, 74k of them trained after the 25,600 random ones), SCHEME (default full).
# The device machine has torch, pytest and pytest-xdist but none of the package's other requirements: put their wheels
# for its Python (3.12) in .whl/ (git-ignored; the device tool's README says how to download them) and carry it.
# On a CPU, to check the script: DEVICE=cpu SEEDS=0,1 EPISODES=1100 SKIP_TESTS=1 OUT=/tmp/out bash benchmarks/paper_n5/gpu_check.sh
set -u
OUT="${OUT:?set OUT to a folder for the outputs}"
DEVICE="${DEVICE:-cuda}"
EPISODES="${EPISODES:-4000}"
SCHEME="${SCHEME:-full}"
SEEDS="${SEEDS:-$(seq -s, 0 30)}"
source benchmarks/device_setup.sh  # the carried wheels installed; the machine described in $OUT/device.txt
if [ -z "${SKIP_TESTS:-}" ]; then
    # Every test file with a CUDA case (they skip without a GPU, so CI never runs them).
    timeout 150 python3 -m pytest -q -p no:cacheprovider -n 8 -m "not slow" tests/run_group tests/envs/test_torch_worlds.py \
        tests/sharing/test_per_agent_sharing.py tests/maddpg/test_run.py tests/experiments/test_batched_backend.py \
        -rs >"$OUT/cuda_tests.log" 2>&1
    echo "CUDA tests: exit $?"; tail -5 "$OUT/cuda_tests.log"
fi
RESULTS=/tmp/gpu_runs
timeout "${RUN_TIMEOUT:-240}" python3 -m sb3_maddpg run --config benchmarks/paper_n5/exp1.json --name gpu_exp1 \
    --schemes "$SCHEME" --seeds "$SEEDS" --episodes "$EPISODES" --backend batched --device "$DEVICE" \
    --results "$RESULTS" >"$OUT/run.log" 2>&1
echo "run: exit $?"; tail -5 "$OUT/run.log"
python3 benchmarks/paper_n5/gpu_summary.py "$RESULTS/gpu_exp1" | tee "$OUT/gpu_summary.md"
tar czf "$OUT/gpu_runs.tar.gz" --exclude='*.zip' --exclude='*.pt' -C "$RESULTS" . 2>/dev/null
