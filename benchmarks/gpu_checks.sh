#!/usr/bin/env bash
# Every GPU check in one command of at most 9.5 minutes, for a lent GPU machine (docs/gpu.md): install the
# carried wheels (make wheels), run the CUDA tests, the parity check and the speed table (CPU, eager CUDA, CUDA
# graphs at K = 40), Adam's fused kernel as one (K, P) tensor against one tensor per row at K = 330, the whole
# paper's projection on the GPU (benchmarks/bench_paper.py), then two and eight processes sharing the card,
# time-sliced and under CUDA MPS (benchmarks/bench_gpu_share.py). Each step has its own time limit, so one
# that hangs cannot cost the others; the log is also written to $OUT/gpu_checks.log (or ./gpu_checks.log).
#
#     bash benchmarks/gpu_checks.sh
set -uo pipefail  # no -e: one failing step (say a CUDA test) must not cost the lent minutes of the others
python3 -m pip install -q --no-index --no-deps --no-compile --upgrade --target /tmp/site wheels/*.whl || exit 1
export PYTHONPATH="/tmp/site:$PWD" PYTHONUNBUFFERED=1

step() {  # run one check under a time limit (seconds, first); say so when it fails or runs out, then go on
    local limit=$1; shift
    echo "== $* (at most ${limit} s; $(date +%T))"
    timeout "$limit" "$@" || echo "!! failed or cut at ${limit} s (exit $?): $*"
}

{
    step 10 nvidia-smi -L
    step 30 python3 -c "import torch; print('torch', torch.__version__, 'cuda', torch.cuda.is_available())"
    step 90 python3 -m pytest -q -p no:cacheprovider -n 3 --dist loadfile tests/train/agent/test_train_staging.py \
        tests/train/agent/test_train_dqn.py tests/train/test_train_packed.py
    step 60 python3 benchmarks/bench_gpu.py --ks 40 --epochs 2
    step 45 python3 benchmarks/bench_gpu.py --ks 330 --epochs 2 --modes "cuda graphs" --adam flat
    step 45 python3 benchmarks/bench_gpu.py --ks 330 --epochs 2 --modes "cuda graphs" --adam per-row
    # the whole paper's projection, every grid-task pack at its full K (the food collector's cost is its
    # physics on the host: time it with --device cpu)
    step 215 python3 benchmarks/bench_paper.py --device cuda --epochs 1 \
        --tasks salad walled-salad hunting scavenging factory
    step 90 python3 benchmarks/bench_gpu_share.py --procs 2 8 --k 40 --epochs 2
    echo "== done $(date +%T)"
} 2>&1 | tee "${OUT:-.}/gpu_checks.log"
