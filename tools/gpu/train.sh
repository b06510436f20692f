#!/usr/bin/env bash
# Training at scale on a lent GPU whose calls last at most 10 minutes: each call trains one slice and leaves the
# run's checkpoints where the next call resumes them. Two jobs:
#   a7-rank1  the joint rank-1 DOE + network design at the A7's scale (issue 18) -> runs/a7-rank1
#   shipped   the shipped network and then its partner fine-tuned behind the shipped PSF (issue 17), on 512^2
#             crops of the training photographs and procedural night scenes -> runs/shipped-gpu
#
# Here, once (the photographs and the OpenEXR wheel the device lacks; both ignored by git):
#   bash tools/gpu/train.sh prepare   # -> gpu-data/a, b, c (the 35 training photographs, 55 MB in three
#                                     #    parts), gpu-data/d (../shared/data/hdr, 11 MB), .whl/openexr-*.whl
# On the device (the `run` tool): a call carries at most 64 MiB together with the 34 MiB working tree, and what
# a call carried stays while the machine is warm. So: three calls carry gpu-data/a, gpu-data/b and gpu-data/c
# (about 18 MiB each) and run `true`; the fourth carries gpu-data/d and .whl and runs a slice; later calls carry
# nothing and run
#   bash tools/gpu/train.sh slice JOB 540   # trains for 540 s, copies the checkpoints + logs to $OUT
# What comes back has the run folder's layout (checkpoint.pt, partner/checkpoint.pt, ...): copy it into the run
# folder here; to resume on a fresh machine, carry that folder in a call of its own (after the data).
# a7-rank1: ship the finished run (model.pt, psf.exr, loss.png) with tools/ship_table2.py. shipped: measure
# RUN/model.pt with RUN/model-partner.pt as tools/results/real-data/README.md measures a pair, against a rule
# written first, then ship with tools/ship_checkpoint.py.
# STEPS, CROP, BATCH, DATA, RUN override a job's defaults (a CPU smoke test: CROP=64 BATCH=1 STEPS=2
# DATA=procedural).
set -euo pipefail
cd "$(dirname "$0")/../.."
case "${1:-}" in
prepare)
    rm -rf gpu-data  # made here from the current split alone: no photograph of an earlier split stays
    mkdir -p gpu-data/a gpu-data/b gpu-data/c gpu-data/d .whl
    exclude=$(git rev-parse --git-path info/exclude)
    mkdir -p "$(dirname "$exclude")" && touch "$exclude"
    grep -qx '/gpu-data/' "$exclude" || echo /gpu-data/ >> "$exclude"
    grep -qx '/.whl/' "$exclude" || echo /.whl/ >> "$exclude"
    parts=(a b c); index=0  # the training split (tools/split_hdr_train.py), never validation, dealt into three
    for photo in runs/data/train/*; do cp -L "$photo" "gpu-data/${parts[index % 3]}/"; index=$((index + 1)); done
    cp ../shared/data/hdr/*.exr gpu-data/d/  # the openexr-images photographs, in the shipped network's mixture
    python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
        --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 -d .whl "OpenEXR==3.5.3"
    du -sh gpu-data/* .whl
    ;;
slice)
    job=${2:-}
    if ! python3 -c "import OpenEXR" 2>/dev/null; then  # the device's python lacks it: the carried wheel
        python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl
        export PYTHONPATH=/tmp/site:${PYTHONPATH:-}
    fi
    export PYTHONPATH=$PWD:${PYTHONPATH:-}
    photographs() {  # "gpu-data/a:W,gpu-data/b:W,gpu-data/c:W": the share $1 split in proportion to the parts' files
        local a b c
        a=$(ls gpu-data/a | wc -l); b=$(ls gpu-data/b | wc -l); c=$(ls gpu-data/c | wc -l)
        python3 -c "import sys; s, *n = map(float, sys.argv[1:]); w = [s * k / sum(n) for k in n]
print(','.join(f'gpu-data/{p}:{x:.6f}' for p, x in zip('abc', w)))" "$1" "$a" "$b" "$c"
    }
    case "$job" in
    a7-rank1)
        RUN=${RUN:-runs/a7-rank1}; RUN=${RUN%/}
        args=(design --profile sony-a7-zeiss50-rank1 --doe rank1 --preset fast --steps "${STEPS:-20000}"
              --crop "${CROP:-512}" --batch "${BATCH:-8}" --lr 2e-4
              --data "${DATA:-$(photographs 0.7),procedural:0.3}")
        ;;
    shipped)
        RUN=${RUN:-runs/shipped-gpu}; RUN=${RUN%/}
        args=(finetune --checkpoint hdrcam/checkpoints/simulated-rank1-fast.pt --psf tools/results/shipped-rank1/psf.exr
              --steps "${STEPS:-6000}" --crop "${CROP:-512}" --batch "${BATCH:-8}" --lr 1e-4 --seed 17
              --data "${DATA:-$(photographs 0.6),gpu-data/d:0.1,procedural:0.3}")  # the shipped network's mixture
        ;;
    *)
        echo "usage: $0 slice a7-rank1|shipped [SECONDS]" >&2
        exit 2
        ;;
    esac
    args+=(--precision bfloat16 --channels-last --checkpoint-every 100 --out "$RUN")
    if [ -f "$RUN/config.json" ] && [ ! -f "$RUN/checkpoint.pt" ]; then  # a slice ended before the first save
        mv "$RUN" "$RUN.unsaved-$(date +%s)"  # kept aside; the run starts again
    fi
    [ -f "$RUN/checkpoint.pt" ] && args+=(--resume)
    status=0
    timeout "${3:-540}" python3 -m hdrcam "${args[@]}" || status=$?
    [ $status -eq 0 ] || [ $status -eq 124 ] || exit $status  # a slice ends by its time limit (124)
    if [ -n "${OUT:-}" ]; then  # what a resume needs, in the run folder's layout
        for saved in checkpoint.pt log.jsonl config.json partner/checkpoint.pt partner/log.jsonl partner/config.json \
                     model.pt model-partner.pt; do
            if [ -f "$RUN/$saved" ]; then mkdir -p "$OUT/$(dirname "$saved")"; cp "$RUN/$saved" "$OUT/$saved"; fi
        done
    fi
    tail -n 1 "$RUN/log.jsonl" 2>/dev/null || echo "no step logged yet"
    ;;
*)
    echo "usage: $0 prepare | slice a7-rank1|shipped [SECONDS]" >&2
    exit 2
    ;;
esac
