#!/usr/bin/env bash
# Every GPU check in one command, for a lent GPU machine (docs/gpu.md): install the carried wheels (make wheels),
# run the CUDA tests, the parity check and the speed table (CPU, eager CUDA, CUDA graphs at K = 10, 40, 330),
# then torch's profile of one epoch's updates at K = 40 (3.5 minutes on a lent H200), then the whole paper's projection
# on the GPU (benchmarks/bench_paper.py, at most 5 minutes); the log is also written to $OUT/gpu_checks.log (or
# ./gpu_checks.log).
#
#     bash benchmarks/gpu_checks.sh
set -uo pipefail  # no -e: one failing step (say a CUDA test) must not cost the lent minutes of the others
python3 -m pip install -q --no-index --no-deps --no-compile --upgrade --target /tmp/site wheels/*.whl || exit 1
export PYTHONPATH="/tmp/site:$PWD" PYTHONUNBUFFERED=1

step() {  # run one check; say so when it fails, then go on
    echo "== $*"
    "$@" || echo "!! failed (exit $?): $*"
}

{
    step nvidia-smi -L
    step python3 -c "import torch; print('torch', torch.__version__, 'cuda', torch.cuda.is_available())"
    step python3 -m pytest -q -p no:cacheprovider tests/train/agent/test_train_staging.py tests/train/agent/test_train_dqn.py \
        tests/train/test_train_packed.py
    step python3 benchmarks/bench_gpu.py --ks 10 40 330 --epochs 2
    step python3 benchmarks/bench_gpu.py --profile 40
    # the whole paper's projection, every grid-task pack at its full K (the food collector's cost is its
    # physics on the host: time it with --device cpu); five minutes at most
    step timeout 300 python3 benchmarks/bench_paper.py --device cuda --epochs 2 \
        --tasks salad walled-salad hunting scavenging factory
} 2>&1 | tee "${OUT:-.}/gpu_checks.log"
