#!/usr/bin/env bash
# Issue 44's device check, one call on a lent GPU (run by the device tool from the repository root; $OUT comes back),
# at most 8 minutes (140 s of tests, 165 s per R): the CUDA tests (run groups eager, compiled and captured as CUDA graphs), then env steps/s summed of
# run groups at N=5 (the paper's hyperparameters, 100 worlds per run) eager, compiled and captured at R = 31 and 155,
# each with the paper's two experiments' projected time (benchmarks/run_group_device.py).
# The device machine has torch, pytest and pytest-xdist but none of the package's other requirements: put their wheels
# for its Python (3.12) in .whl/ (git-ignored; the device tool's README says how to download them) and carry it:
#   run(command="OUT=$OUT bash benchmarks/device_check.sh", carry=[".whl"], timeout_s=560)
# On a CPU, to check the script: DEVICE=cpu RUNS="1 2" STEPS=2000 SKIP_TESTS=1 OUT=/tmp/out bash benchmarks/device_check.sh
set -u
OUT="${OUT:?set OUT to a folder for the outputs}"
DEVICE="${DEVICE:-cuda}"
RUNS="${RUNS:-31 155}"
STEPS="${STEPS:-10000}"
BUFFER="${BUFFER:-100000}"  # per run: 155 runs' 1M-transition buffers would not fit; a batch's gathers cost the same
source benchmarks/device_setup.sh  # the carried wheels installed; the machine described in $OUT/device.txt
if [ -z "${SKIP_TESTS:-}" ]; then
    # The test files with CUDA cases (they skip without a GPU, so CI never runs them); the compiled ones compile.
    timeout 140 python3 -m pytest -q -p no:cacheprovider -n 8 tests/run_group tests/envs/test_torch_worlds.py -rs \
        >"$OUT/cuda_tests.log" 2>&1
    echo "CUDA tests: exit $?"; tail -5 "$OUT/cuda_tests.log"
fi
# R = 31: eager, compiled, captured; R = 155: eager and captured (the time left decides what is useful at 155).
for runs in $RUNS; do
    modes="eager compiled captured"
    [ "$runs" -gt 100 ] && modes="eager captured"
    timeout "${BENCH_TIMEOUT:-165}" python3 benchmarks/run_group_device.py --device "$DEVICE" --runs "$runs" \
        --steps "$STEPS" --buffer-size "$BUFFER" --modes $modes 2>&1 | grep --line-buffered -E "^(\||device)" \
        | tee -a "$OUT/device_throughput.md"
done
