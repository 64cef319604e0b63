#!/usr/bin/env bash
# Every GPU check in one command, for a lent GPU machine (docs/gpu.md): install the carried wheels (make wheels),
# run the CUDA tests, the parity check and the speed table (CPU, eager CUDA, CUDA graphs at K = 10, 40, 330),
# then torch's profile of one epoch's updates at K = 40. It takes about 5-8 minutes; the log is also written to
# $OUT/gpu_checks.log (or ./gpu_checks.log).
#
#     bash benchmarks/gpu_checks.sh
set -euo pipefail
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site wheels/*.whl
export PYTHONPATH="/tmp/site:$PWD" PYTHONUNBUFFERED=1
{
    nvidia-smi -L || true
    python3 -c "import torch; print('torch', torch.__version__, 'cuda', torch.cuda.is_available())"
    python3 -m pytest -q -p no:cacheprovider tests/train/agent/test_train_staging.py tests/train/agent/test_train_dqn.py
    python3 benchmarks/bench_gpu.py --ks 10 40 330 --epochs 3
    python3 benchmarks/bench_gpu.py --profile 40 | head -45
} 2>&1 | tee "${OUT:-.}/gpu_checks.log"
