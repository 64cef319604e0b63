#!/usr/bin/env bash
# The whole paper's grid-task packs (benchmarks/bench_paper.py --census) timed side by side on one GPU, a process
# each, under CUDA MPS and then time-sliced: each pack's rate while all the others run, and its projected time.
# Run on a lent GPU machine after `make wheels` (about 5 minutes; root for MPS):
#
#     bash benchmarks/gpu_paper_side_by_side.sh [SECONDS]        # timed epochs per pack (default 60)
set -uo pipefail
python3 -m pip install -q --no-index --no-deps --no-compile --upgrade --target /tmp/site wheels/*.whl || exit 1
export PYTHONPATH="/tmp/site:$PWD" PYTHONUNBUFFERED=1
source benchmarks/mps.sh
SECONDS_TIMED=${1:-60}
TASKS="salad walled-salad hunting scavenging factory"
LOG="${OUT:-.}/gpu_paper_side_by_side.log"
packs=$(python3 benchmarks/bench_paper.py --census --tasks $TASKS | head -1 | sed 's/.* in \([0-9]*\) packs.*/\1/')

side_by_side() {  # every pack in its own process, all at once; their table rows
    local i
    for i in $(seq 0 $((packs - 1))); do
        timeout 400 python3 benchmarks/bench_paper.py --device cuda --epochs 2 --seconds "$SECONDS_TIMED" \
            --tasks $TASKS --pack "$i" > "/tmp/pack$i.log" 2>&1 &
    done
    wait
    for i in $(seq 0 $((packs - 1))); do grep -E '^\| [a-z-]+ \| [0-9]' "/tmp/pack$i.log" || tail -2 "/tmp/pack$i.log"; done
}

{
    nvidia-smi -L
    echo "== $packs packs side by side under CUDA MPS ($(date +%T))"
    if mps_start; then
        side_by_side
        mps_stop
    else
        echo "!! MPS did not start"
    fi
    echo "== $packs packs side by side, time-sliced ($(date +%T))"
    side_by_side
    echo "== done $(date +%T)"
} 2>&1 | tee "$LOG"
