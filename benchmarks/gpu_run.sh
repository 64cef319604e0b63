#!/usr/bin/env bash
# One resumable chunk of an experiment on a lent GPU machine (docs/gpu.md), at most CHUNK_S seconds (default
# 510, so that the trainers' clean stop and the packing fit one 10-minute command):
#
#     bash benchmarks/gpu_run.sh headline-waypoint --budget paper           # repeat until it says "all done"
#     bash benchmarks/gpu_run.sh shaping --task scavenging --budget paper + rnd --budget paper   # side by side
#
# Runs separated by a lone "+" train side by side, one process each (on a lent H200 four processes summed to
# about twice one process's agent-steps/s, docs/gpu.md). From MPS_MIN (default 4) processes on, where
# nvidia-cuda-mps-control is at hand, CUDA MPS shares the card between them (eight processes: 2.7x the
# agent-steps/s of time-slicing; two: 0.87x; docs/gpu.md); MPS_MIN=0 turns it off.
# It installs the carried wheels (`make wheels`) where gymnasium or pymunk is missing, runs `ecorl run ARGS --device $DEVICE
# (cuda) --out results` under `timeout -s INT`, so every trainer stops at the end of an epoch with a
# checkpoint, and packs results/ into gpu-stage/results.tar.gz (split into results.tar.gz.00, .01, ... of 15 MiB
# where it is larger, as the machine's return path wants): config.json, metrics.csv, done.json, visits/, policies/, and
# the checkpoints of the runs not yet finished (gzip -1 takes a 118 MB one to 5.5 MB), never a
# finished run's checkpoint. Into $OUT go at most four parts (60 MiB; a command brings back 64 MiB at most);
# where there are more, `bash benchmarks/gpu_run.sh --rest`, the next command of the same lease, sends the next
# four. The next chunk, in the same lease, resumes from ./results (run it from the
# repository's root: results/ is ignored there, so the machine keeps it between commands while it stays up). A
# later lease resumes from the archive: copy it into the ignored folder gpu-state/ here, carry gpu-state, and
# this script unpacks it where there is no results/ yet. Back here, unpack with
# `cat FILES_AT/results.tar.gz* | tar -xz` (--rest's parts after the first four) and ship like
# docs/results/paper/README.md says (no checkpoints).
set -uo pipefail
out="${OUT:-gpu-out}"
stage="${STAGE:-gpu-stage}"  # the whole archive, kept on the machine until every part is sent
parts_per_command=4  # of 15 MiB: 60 MiB, under the 64 MiB a command brings back
send_parts() {  # the next (at most) $parts_per_command unsent parts of the archive into $out
    rm -f "$out"/results.tar.gz*
    [[ -f "$stage/unsent" ]] || return 1
    local part
    head -n "$parts_per_command" "$stage/unsent" | while read -r part; do cp "$stage/$part" "$out/"; done
    tail -n "+$(( parts_per_command + 1 ))" "$stage/unsent" > "$stage/unsent.next" && mv "$stage/unsent.next" "$stage/unsent"
    if [[ -s "$stage/unsent" ]]; then
        echo "== $(wc -l < "$stage/unsent") more part(s) of the archive wait here: run \`bash benchmarks/gpu_run.sh --rest\`" \
            "next, before the machine goes back"
    fi
}
if [[ ${1:-} == --rest ]]; then
    mkdir -p "$out"
    [[ -f "$stage/unsent" ]] || { echo "nothing to send: no chunk has packed an archive here" >&2; exit 2; }
    send_parts
    exit 0
fi
if (( $# == 0 )) || [[ $1 == -h || $1 == --help ]]; then
    echo "usage: bash benchmarks/gpu_run.sh EXPERIMENT [ecorl run options] [+ EXPERIMENT [options]] ..." >&2
    echo "(one chunk of at most CHUNK_S seconds; see the comment at the top of this script)" >&2
    exit 2
fi
root="$(cd "$(dirname "$0")/.." && pwd)"
if ! python3 -c "import gymnasium, pymunk" 2> /dev/null && compgen -G "$root/wheels/*.whl" > /dev/null; then
    python3 -m pip install -q --no-index --no-deps --no-compile --upgrade --target /tmp/site "$root"/wheels/*.whl || exit 1
    export PYTHONPATH="/tmp/site:$root${PYTHONPATH:+:$PYTHONPATH}"
else  # keep the caller's path: gymnasium may be importable only through it (installed by an earlier step)
    export PYTHONPATH="$root${PYTHONPATH:+:$PYTHONPATH}"
fi
export PYTHONUNBUFFERED=1

pack_results() {  # results/ into $1/results.tar.gz[.NN] (their names in $1/unsent): no locks, no progress files,
    # no finished run's checkpoint
    local finished
    finished=$(mktemp)
    rm -f "$1"/results.tar.gz* "$1/unsent"
    find results -name done.json 2> /dev/null | sed 's|/done.json$|/checkpoint*|' > "$finished"
    tar -I "gzip -1" -cf "$1/results.tar.gz" --exclude='*.lock' --exclude='.lock' --exclude='progress.json' \
        -X "$finished" results
    local packed=$?
    rm -f "$finished"
    (( packed == 0 )) || return 1
    if (( $(stat -c %s "$1/results.tar.gz") > 15 * 1024 * 1024 )); then
        split -b 15M -d -a 2 "$1/results.tar.gz" "$1/results.tar.gz." && rm "$1/results.tar.gz"
    fi
    (cd "$1" && ls results.tar.gz*) > "$1/unsent"
    echo "== packed: $(du -ch "$1"/results.tar.gz* | tail -1 | cut -f1) in $(wc -l < "$1/unsent") file(s)"
    local unfinished
    unfinished=$(find results -name checkpoint.npz 2> /dev/null | sed 's|checkpoint.npz$|done.json|' \
        | while read -r done; do [[ -e $done ]] || echo; done | wc -l)
    if (( unfinished )); then
        echo "== $unfinished unfinished runs travel with their checkpoints: a later lease can carry them back in" \
            "gpu-state/ only if they and the working tree fit 64 MiB together; else resume them on any CPU machine"
    fi
}
mkdir -p "$out" "$stage"
state="${STATE:-gpu-state}"  # an earlier lease's archive, carried here
if [[ ! -e results ]] && compgen -G "$state/results.tar.gz*" > /dev/null; then
    cat "$state"/results.tar.gz* | tar -xzf - || exit 1
    echo "== resumed from $state: $(find results -name checkpoint.npz | wc -l) unfinished runs"
fi
each_spec() {  # call $1 with each run's arguments: the rest of the line, split at the arguments "+"
    local fn=$1 spec=() arg
    shift
    for arg in "$@" +; do
        if [[ $arg == + ]]; then
            (( ${#spec[@]} )) && "$fn" "${spec[@]}"
            spec=()
        else
            spec+=("$arg")
        fi
    done
}
pids=()
start_run() {
    timeout -s INT "${CHUNK_S:-510}" python3 -m train.cli run "$@" --device "${DEVICE:-cuda}" --out results \
        --no-progress &
    pids+=($!)
}
print_status() { python3 -m train.cli run "$@" --device "${DEVICE:-cuda}" --out results --dry-run; }

count_run() { runs=$(( runs + 1 )); }
start_mps() {  # CUDA MPS for many processes side by side; left running for the next chunk of the lease
    local min=${MPS_MIN:-4}
    (( min > 0 && runs >= min )) && [[ ${DEVICE:-cuda} == cuda* ]] && command -v nvidia-cuda-mps-control > /dev/null \
        || return 0
    source "$(dirname "${BASH_SOURCE[0]}")/mps.sh"
    if mps_start; then
        echo "== CUDA MPS shares the card between the $runs processes"
    else
        echo "== CUDA MPS did not start: the $runs processes time-slice the card"
    fi
}

runs=0
each_spec count_run "$@"
start_mps
began=$(date +%s)
each_spec start_run "$@"
code=0
for pid in "${pids[@]}"; do
    wait "$pid"
    status=$?
    if (( status != 0 && status != 124 )) || (( code == 0 )); then  # a failure outranks 124 (stopped in time)
        code=$status
    fi
done
echo "== chunk: exit $code after $(( $(date +%s) - began )) s"
pack_results "$stage"
each_spec print_status "$@" | tee "$out/status.txt"
if (( code != 0 && code != 124 )); then  # 124: stopped at the chunk's end, as planned
    echo "== failed: exit $code (the error is above)"
elif [[ ! -s "$out/status.txt" ]] || grep -q -v '^\[  done\]' "$out/status.txt"; then
    echo "== not finished: run this again"
else
    echo "== all done"
fi
send_parts
exit $code
