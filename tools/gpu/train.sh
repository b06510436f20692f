#!/usr/bin/env bash
# Training at scale on a lent GPU. A lease gives 15 minutes of device time in all (the start included), a
# call at most 10, and a machine stays warm 30 s after a call. Two jobs:
#   a7-rank1  the joint rank-1 DOE + network design at the A7's scale (issue 18) -> runs/a7-rank1, in resumable
#             slices: `slice a7-rank1 SECONDS`
#   shipped   the shipped network and its partner, each fine-tuned behind the shipped PSF in its own mixture
#             (issue 17), on 512^2 crops of the training photographs and procedural night scenes, side by side
#             on the one GPU, for as many steps as fit: `fit shipped SECONDS` -> runs/shipped-gpu/main, .../partner
#
# Here, once (the photographs and the OpenEXR wheel the device lacks; both ignored by git):
#   bash tools/gpu/train.sh prepare   # -> gpu-data/a, b, c (the 35 training photographs gzipped, dealt by size),
#                                     #    gpu-data/d (../shared/data/hdr), .whl/openexr-*.whl; prints the carries
# A call carries at most 64 MiB together with the working tree (41 MiB), and what a call carried is gone at
# the next call (seen 2026-11-26), while /tmp stays as long as the machine is warm: every command here first
# keeps the call's carried parts in /tmp/hdrcam-carry and puts back those of earlier calls. So three calls,
# each sent within 30 s of the last one's return:
#   1. carry gpu-data/a + .whl, run `bash tools/gpu/train.sh smoke`  (imports, CUDA, two tiny steps: 25 s)
#   2. carry gpu-data/b, run `bash tools/gpu/train.sh keep`
#   3. carry gpu-data/c + gpu-data/d, run `bash tools/gpu/train.sh fit shipped SECONDS`
# `fit` first times 40 steps of both networks side by side (the step time of the real runs, data drawing and
# the shared GPU included), then runs both for the steps that fit in what is left of SECONDS, so each ends on
# its own learning-rate schedule and writes model.pt; $OUT gets each run's model.pt (else its checkpoint.pt),
# log.jsonl and config.json, and timing.txt. Measure runs/shipped-gpu/main/model.pt with
# runs/shipped-gpu/partner/model.pt as tools/results/real-data/README.md measures a pair, against a rule
# written first, then ship with tools/ship_checkpoint.py.
# a7-rank1: ship the finished run (model.pt, psf.exr, loss.png) with tools/ship_table2.py. Its slices resume the
# run folder a call left: /tmp was seen to stay between calls, the tree's ignored runs/ was not checked, so give
# RUN=/tmp/a7-rank1. Across sessions: commit $OUT's checkpoint.pt.gz, config.json and log.jsonl at once (as
# leg10/ was: into a folder, then out of the tree in the next commit), and in the next session run
# `A7_FROM=REV:FOLDER bash tools/gpu/train.sh prepare`, which puts them in gpu-data/a7-run for the third carry
# (the slice needs no gpu-data/d, whose room it takes); the slice starts from them where RUN holds no run.
# STEPS, CROP, BATCH, DATA, RUN override a job's defaults (a CPU smoke test: CROP=64 BATCH=1 STEPS=2
# DATA=procedural).
set -euo pipefail
cd "$(dirname "$0")/../.."
tree_mib() {  # what the tracked working tree weighs, MiB (it travels with every call)
    git ls-files -z | xargs -0 stat -c %s 2>/dev/null | awk '{total += $1} END {print total / 1048576}'
}
CARRY_MIB=$(awk -v tree="$(tree_mib)" 'BEGIN {print int(64 - tree - 1)}')  # each call's carry: 64 MiB less
# the working tree (41 MiB on 2026-11-27) and a margin of 1 MiB

keep_carries() {  # this call's carried parts into /tmp/hdrcam-carry, and the earlier calls' back from there
    local kept=/tmp/hdrcam-carry
    mkdir -p "$kept/gpu-data" gpu-data
    for part in gpu-data/* .whl; do
        if [ -d "$part" ] && [ -n "$(ls -A "$part")" ]; then
            mkdir -p "$kept/$part" && cp -r "$part/." "$kept/$part/"
        fi
    done
    cp -r "$kept/gpu-data/." gpu-data/
    find gpu-data -name '*.gz' -exec gunzip -f {} +  # prepare gzips the photographs (11 % less to carry)
    if [ -d "$kept/.whl" ]; then mkdir -p .whl && cp -r "$kept/.whl/." .whl/; fi
}

device_python() {  # the device's python lacks OpenEXR: the carried wheel, installed once; hdrcam from this tree
    keep_carries
    if ! python3 -c "import OpenEXR" 2>/dev/null; then
        if ! PYTHONPATH=/tmp/site python3 -c "import OpenEXR" 2>/dev/null; then
            python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl
        fi
        export PYTHONPATH=/tmp/site:${PYTHONPATH:-}
    fi
    export PYTHONPATH=$PWD:${PYTHONPATH:-}
}

photographs() {  # "gpu-data/a:W,gpu-data/b:W,gpu-data/c:W": the share $1 split in proportion to the parts' files
    local a b c
    a=$(ls gpu-data/a | wc -l); b=$(ls gpu-data/b | wc -l); c=$(ls gpu-data/c | wc -l)
    python3 -c "import sys; s, *n = map(float, sys.argv[1:]); w = [s * k / sum(n) for k in n]
print(','.join(f'gpu-data/{p}:{x:.6f}' for p, x in zip('abc', w)))" "$1" "$a" "$b" "$c"
}

finetune_args() {  # the arguments of network $1 (main | partner) of job shipped, for $2 steps
    local start data seed
    case "$1" in
    main) start=hdrcam/checkpoints/simulated-rank1-fast.pt; seed=17
          data=${DATA:-$(photographs 0.6),gpu-data/d:0.1,procedural:0.3} ;;  # the shipped network's mixture
    partner) start=hdrcam/checkpoints/simulated-rank1-fast-partner.pt; seed=18
          data=${DATA:-$(photographs 0.35),gpu-data/d:0.1,procedural:0.55} ;;  # the night-leaning partner's
    esac
    echo finetune --checkpoint "$start" --no-partner --psf tools/results/shipped-rank1/psf.exr --steps "$2" \
        --crop "${CROP:-512}" --batch "${BATCH:-8}" --lr 2e-4 --seed "$seed" --data "$data" \
        --precision bfloat16 --channels-last --checkpoint-every 100 --no-check  # the rule measures a pair
}

case "${1:-}" in
prepare)
    rm -rf gpu-data  # made here from the current split alone: no photograph of an earlier split stays
    mkdir -p gpu-data/a gpu-data/b gpu-data/c gpu-data/d .whl
    exclude=$(git rev-parse --git-path info/exclude)
    mkdir -p "$(dirname "$exclude")" && touch "$exclude"
    grep -qx '/gpu-data/' "$exclude" || echo /gpu-data/ >> "$exclude"
    grep -qx '/.whl/' "$exclude" || echo /.whl/ >> "$exclude"
    cp ../shared/data/hdr/*.exr gpu-data/d/  # the openexr-images photographs, in the shipped network's mixture
    if [ -n "${A7_FROM:-}" ]; then  # REV:FOLDER, an a7-rank1 slice's files committed there: the run to resume
        mkdir -p gpu-data/a7-run
        for saved in checkpoint.pt.gz config.json log.jsonl; do  # the device unpacks the .gz as it keeps it
            git show "$A7_FROM/$saved" > "gpu-data/a7-run/$saved"
        done
    fi
    python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
        --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 -d .whl "OpenEXR==3.5.3"
    # the training split (tools/split_hdr_train.py), never validation, dealt largest first into the part with
    # the most room: a travels with .whl, b alone, c with gpu-data/d
    python3 - "$CARRY_MIB" <<'DEAL'
import gzip, sys
from pathlib import Path
mib = 2 ** 20
room = {"a": float(sys.argv[1]) * mib - sum(f.stat().st_size for f in Path(".whl").iterdir()),
        "b": float(sys.argv[1]) * mib,
        "c": float(sys.argv[1]) * mib - max(sum(f.stat().st_size for f in Path(part).iterdir())
                                             for part in ("gpu-data/d", "gpu-data/a7-run") if Path(part).is_dir())}
packed = {photo.name: gzip.compress(photo.read_bytes(), 6) for photo in Path("runs/data/train").iterdir()}
for name in sorted(packed, key=lambda name: -len(packed[name])):
    part = max(room, key=room.get)
    if room[part] < len(packed[name]):
        sys.exit(f"error: the training photographs do not fit three carries of {sys.argv[1]} MiB")
    Path("gpu-data", part, name + ".gz").write_bytes(packed[name])
    room[part] -= len(packed[name])
DEAL
    du -sh gpu-data/* .whl
    echo "carries: 1. gpu-data/a .whl (smoke)  2. gpu-data/b (keep)  3. gpu-data/c gpu-data/d (fit shipped SECONDS)"
    echo "         or 3. gpu-data/c gpu-data/a7-run (slice a7-rank1 SECONDS; a7-run only with A7_FROM)"
    ;;
keep)  # on the device: a call that only carries
    keep_carries
    ls gpu-data
    ;;
smoke)  # on the device after the first carry: CUDA, imports, two tiny steps of each network side by side
    device_python
    python3 -c "import torch; print(torch.__version__, torch.cuda.get_device_name(0))"
    rm -rf runs/gpu-smoke
    # shellcheck disable=SC2046
    python3 -m hdrcam $(DATA=gpu-data/a:0.9,procedural:0.1 CROP=64 BATCH=2 finetune_args main 2) \
        --out runs/gpu-smoke/main &
    # shellcheck disable=SC2046
    python3 -m hdrcam $(DATA=gpu-data/a:0.9,procedural:0.1 CROP=64 BATCH=2 finetune_args partner 2) \
        --out runs/gpu-smoke/partner
    wait
    tail -n 1 runs/gpu-smoke/main/log.jsonl runs/gpu-smoke/partner/log.jsonl
    ;;
fit)  # fit shipped SECONDS: both networks side by side, for the steps that fit in SECONDS
    [ "${2:-}" = shipped ] || { echo "usage: $0 fit shipped SECONDS" >&2; exit 2; }
    budget_s=${3:-540}; began=$SECONDS
    device_python
    RUN=${RUN:-runs/shipped-gpu}; RUN=${RUN%/}
    rm -rf "$RUN" "$RUN.timing"
    pair() {  # both networks for $1 steps into $2/main and $2/partner, killed at $3 seconds; exit statuses
        local main_status=0 partner_status=0
        # shellcheck disable=SC2046
        timeout "$3" python3 -m hdrcam $(finetune_args main "$1") --out "$2/main" & local main_pid=$!
        # shellcheck disable=SC2046
        timeout "$3" python3 -m hdrcam $(finetune_args partner "$1") --out "$2/partner" || partner_status=$?
        wait "$main_pid" || main_status=$?
        echo "main $main_status partner $partner_status"
    }
    timing_steps=${TIMING_STEPS:-40}
    timing_began=$SECONDS
    pair "$timing_steps" "$RUN.timing" 240
    timing_wall_s=$((SECONDS - timing_began))
    step_s=$(python3 - "$RUN.timing" "$timing_steps" <<'TIME'
import json, statistics, sys
from pathlib import Path
times = []
for name in ("main", "partner"):  # the mean of the steps after the first 10 (CUDA and cuDNN warming up)
    lines = Path(sys.argv[1], name, "log.jsonl").read_text().splitlines()[10:]
    times.append(statistics.mean(json.loads(line)["seconds"] for line in lines))
print(f"{max(times):.4f}")
TIME
)
    left_s=$((budget_s - (SECONDS - began)))
    # the timing pair's wall time less its steps: starting (imports, photographs, CUDA) and writing the results
    steps=${STEPS:-$(python3 -c "import sys; left, step, wall, n = map(float, sys.argv[1:])
print(max(10, int((left - 10 - (wall - n * step)) / step * 0.92) // 10 * 10))" \
        "$left_s" "$step_s" "$timing_wall_s" "$timing_steps")}
    echo "step ${step_s} s with both networks; timing pair ${timing_wall_s} s for ${timing_steps} steps;" \
         "${left_s} s left: ${steps} steps each" | tee "$RUN.timing/timing.txt"
    statuses=$(pair "$steps" "$RUN" $((left_s - 5)))
    echo "$statuses; trained in $((SECONDS - began)) s of ${budget_s}" | tee -a "$RUN.timing/timing.txt"
    if [ -n "${OUT:-}" ]; then  # $OUT/main/..., $OUT/partner/...: the run folders' files a measurement needs
        cp "$RUN.timing/timing.txt" "$OUT/"
        for net in main partner; do
            mkdir -p "$OUT/$net"
            for saved in log.jsonl config.json; do cp "$RUN/$net/$saved" "$OUT/$net/" 2>/dev/null || true; done
            cp "$RUN/$net/model.pt" "$OUT/$net/" 2>/dev/null || cp "$RUN/$net/checkpoint.pt" "$OUT/$net/" || true
        done
    fi
    tail -n 1 "$RUN/main/log.jsonl" "$RUN/partner/log.jsonl"
    ;;
slice)
    [ "${2:-}" = a7-rank1 ] || { echo "usage: $0 slice a7-rank1 [SECONDS]" >&2; exit 2; }
    device_python
    RUN=${RUN:-runs/a7-rank1}; RUN=${RUN%/}
    start=hdrcam/checkpoints/table2/rank1.pt  # the PSF-first rank-1 design and its 800-step network (README)
    args=(design --profile sony-a7-zeiss50-rank1 --doe rank1 --preset fast --steps "${STEPS:-20000}"
          --init "$start" --init-doe "$start"
          --crop "${CROP:-512}" --batch "${BATCH:-8}" --lr 2e-4
          --data "${DATA:-$(photographs 0.7),procedural:0.3}"
          --precision bfloat16 --channels-last --checkpoint-every 100 --out "$RUN")
    if [ -f gpu-data/a7-run/checkpoint.pt ] && [ ! -f "$RUN/checkpoint.pt" ]; then  # carried from a past session
        mkdir -p "$RUN" && cp gpu-data/a7-run/* "$RUN/"
    fi
    if [ -f "$RUN/config.json" ] && [ ! -f "$RUN/checkpoint.pt" ]; then  # a slice ended before the first save
        mv "$RUN" "$RUN.unsaved-$(date +%s)"  # kept aside; the run starts again
    fi
    [ -f "$RUN/checkpoint.pt" ] && args+=(--resume)
    status=0
    timeout "${3:-540}" python3 -m hdrcam "${args[@]}" || status=$?
    [ $status -eq 0 ] || [ $status -eq 124 ] || exit $status  # a slice ends by its time limit (124)
    if [ -n "${OUT:-}" ]; then  # what a resume needs, in the run folder's layout; the checkpoint (17 MB at
        # 64 px crops, its DOE's 1527^2 heights 9.4 MB of it) gzipped under the 16 MiB a file may bring back
        for saved in log.jsonl config.json model.pt; do
            if [ -f "$RUN/$saved" ]; then cp "$RUN/$saved" "$OUT/$saved"; fi
        done
        if [ -f "$RUN/checkpoint.pt" ]; then gzip -1 -c "$RUN/checkpoint.pt" > "$OUT/checkpoint.pt.gz"; fi
    fi
    tail -n 1 "$RUN/log.jsonl" 2>/dev/null || echo "no step logged yet"
    ;;
*)
    echo "usage: $0 prepare | keep | smoke | fit shipped SECONDS | slice a7-rank1 [SECONDS]" >&2
    exit 2
    ;;
esac
