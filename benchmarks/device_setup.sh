# Sourced by the device checks (benchmarks/device_check.sh, benchmarks/paper_n5/gpu_check.sh) on a lent GPU: the
# package's requirements installed from the carried wheels (.whl/: the machine has torch and pytest, not the rest),
# and what the machine is, in $OUT/device.txt.
export SDL_VIDEODRIVER=dummy PYTHONUNBUFFERED=1
if ! python3 -c "import stable_baselines3" 2>/dev/null; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
    export PYTHONPATH="/tmp/site:$PWD"
fi
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv 2>&1 | tee "$OUT/device.txt"
python3 -c "import torch, stable_baselines3, sb3_maddpg; print('torch', torch.__version__, 'cuda', torch.cuda.is_available(), 'sb3', stable_baselines3.__version__)" | tee -a "$OUT/device.txt"
