#!/usr/bin/env bash
# The joint rank-1 DOE + network design at the A7's scale (issues 17/18), for a lent GPU whose calls last at most
# 10 minutes: each call trains one slice and leaves the run's checkpoint where the next call resumes it.
#
# Here, once (the photographs and the OpenEXR wheel the device lacks; both ignored by git):
#   bash tools/gpu/train-a7-rank1.sh prepare   # -> gpu-data/a, gpu-data/b (the 35 training photographs, 55 MB
#                                              #    in two halves), .whl/openexr-*.whl (1.7 MB)
# On the device (the `run` tool; a call carries at most 64 MiB with the 34 MiB working tree, and what it carried
# stays while the machine is warm): first call carry gpu-data/a and run `true`; then each call carry gpu-data/b,
# .whl and runs/a7-rank1, and run
#   bash tools/gpu/train-a7-rank1.sh slice 540   # trains for 540 s, copies checkpoint + log to $OUT
# The finished run (model.pt, psf.exr, loss.png) is in runs/a7-rank1; ship it with tools/ship_table2.py.
# STEPS, CROP, BATCH, DATA, RUN override the defaults (a CPU smoke test: CROP=64 BATCH=1 STEPS=2).
set -euo pipefail
cd "$(dirname "$0")/../.."
RUN=${RUN:-runs/a7-rank1}
case "${1:-}" in
prepare)
    mkdir -p gpu-data/a gpu-data/b .whl
    exclude=$(git rev-parse --git-path info/exclude)
    mkdir -p "$(dirname "$exclude")" && touch "$exclude"
    grep -qx '/gpu-data/' "$exclude" || echo /gpu-data/ >> "$exclude"
    grep -qx '/.whl/' "$exclude" || echo /.whl/ >> "$exclude"
    half=a  # the training split (tools/split_hdr_train.py), never validation, alternately into two halves
    for photo in runs/data/train/*; do cp -L "$photo" "gpu-data/$half/"; half=$([ $half = a ] && echo b || echo a); done
    python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
        --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 -d .whl "OpenEXR==3.5.3"
    du -sh gpu-data .whl
    ;;
slice)
    if ! python3 -c "import OpenEXR" 2>/dev/null; then  # the device's python lacks it: the carried wheel
        python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl
        export PYTHONPATH=/tmp/site:${PYTHONPATH:-}
    fi
    export PYTHONPATH=$PWD:${PYTHONPATH:-}
    args=(design --profile sony-a7-zeiss50-rank1 --doe rank1 --preset fast --steps "${STEPS:-20000}"
          --crop "${CROP:-512}" --batch "${BATCH:-8}" --lr 2e-4 --data "${DATA:-gpu-data/a:0.35,gpu-data/b:0.35,procedural:0.3}"
          --precision bfloat16 --channels-last --checkpoint-every 100 --out "$RUN")
    [ -f "$RUN/checkpoint.pt" ] && args+=(--resume)
    timeout "${2:-540}" python3 -m hdrcam "${args[@]}" || [ $? -eq 124 ]  # a slice ends by its time limit
    [ -n "${OUT:-}" ] && cp "$RUN/checkpoint.pt" "$RUN/log.jsonl" "$OUT/"
    tail -n 1 "$RUN/log.jsonl"
    ;;
*)
    echo "usage: $0 prepare | slice [SECONDS]" >&2
    exit 2
    ;;
esac
