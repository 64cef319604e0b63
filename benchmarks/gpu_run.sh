#!/usr/bin/env bash
# One resumable chunk of an experiment on a lent GPU machine (docs/gpu.md), at most CHUNK_S seconds (default
# 510, so that the trainers' clean stop and the packing fit one 10-minute command):
#
#     bash benchmarks/gpu_run.sh headline-waypoint --budget paper           # repeat until it says "all done"
#
# It installs the carried wheels (`make wheels`) where gymnasium or pymunk is missing, runs `ecorl run ARGS --device $DEVICE
# (cuda) --out results` under `timeout -s INT`, so every trainer stops at the end of an epoch with a
# checkpoint, and packs what is small (config.json, metrics.csv, done.json, visits/, policies/, never a
# checkpoint) into $OUT/results.tar.gz: one file, as the machine's return path wants. The next chunk, in the
# same lease, resumes from the checkpoints left in ./results (run it from the repository's root: results/ is
# ignored there, so the machine keeps it between commands while it stays up). Back here, unpack with
# `tar -xzf FILES_AT/results.tar.gz` and ship like docs/results/paper/README.md says.
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
if ! python3 -c "import gymnasium, pymunk" 2> /dev/null && compgen -G "$root/wheels/*.whl" > /dev/null; then
    python3 -m pip install -q --no-index --no-deps --no-compile --upgrade --target /tmp/site "$root"/wheels/*.whl || exit 1
    export PYTHONPATH="/tmp/site:$root"
else
    export PYTHONPATH="$root"
fi
export PYTHONUNBUFFERED=1
out="${OUT:-gpu-out}"
mkdir -p "$out"
began=$(date +%s)
timeout -s INT "${CHUNK_S:-510}" python3 -m train.cli run "$@" --device "${DEVICE:-cuda}" --out results --no-progress
code=$?
echo "== chunk: exit $code after $(( $(date +%s) - began )) s"
tar -czf "$out/results.tar.gz" --exclude='checkpoint*' --exclude='*.lock' --exclude='.lock' \
    --exclude='progress.json' results
python3 -m train.cli run "$@" --device "${DEVICE:-cuda}" --out results --dry-run | tee "$out/status.txt"
grep -q -v '^\[  done\]' "$out/status.txt" && echo "== not finished: run this again" || echo "== all done"
exit $code
