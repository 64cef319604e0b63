# CUDA MPS for the lent-GPU scripts (docs/gpu.md), sourced: `source benchmarks/mps.sh`. Its daemon multiplexes the
# kernels of every process on the card; eight training processes ran 2.7x the agent-steps/s of time-slicing.

mps_start() {  # start the daemon (or find it running) with its folders under /tmp; 0 when it runs
    command -v nvidia-cuda-mps-control > /dev/null || return 1
    export CUDA_MPS_PIPE_DIRECTORY=/tmp/ecorl-mps/pipe CUDA_MPS_LOG_DIRECTORY=/tmp/ecorl-mps/log
    mkdir -p "$CUDA_MPS_PIPE_DIRECTORY" "$CUDA_MPS_LOG_DIRECTORY"
    pgrep -x nvidia-cuda-mps-control > /dev/null || nvidia-cuda-mps-control -d
}

mps_stop() {  # ask the daemon to quit; later processes time-slice the card
    echo quit | nvidia-cuda-mps-control
    sleep 2
    unset CUDA_MPS_PIPE_DIRECTORY CUDA_MPS_LOG_DIRECTORY
}
