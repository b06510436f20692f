#!/usr/bin/env bash
# The generalisation issue's five measurements: validation photographs, procedural night scenes, independent
# night scenes, training photographs (evaluate, one thread each) and the RAW path (tools/bench_raw_path.py); the
# four besides the independent scenes as tools/results/real-data/README.md records them. The independent scenes
# are tools/independent_night_scenes.py's test-only set (24 scenes, seed 7), from a generator written without
# reading the project's, which the networks trained on: generated into OUT/independent-scenes (log
# OUT/independent-gen.log) and deleted after their evaluate (255 MB; the seed reproduces them). Each run's
# summary.md shows the mean gain over the LDR capture, the worst image and how many fall more than 0.3 dB below
# it; OUT/seconds.txt has the wall times (evaluate's alone for the independent scenes).
# Usage: bash tools/measure_generalisation.sh OUT [--checkpoint CKPT] [--partner CKPT | --no-partner]
# Paths are taken from the repository root. (runs/data from `python tools/split_hdr_train.py
# ../shared/data/hdr-train --out runs/data`.) A failed step stops the script: its log is OUT/NAME.log.
set -euo pipefail
cd "$(dirname "$0")/.."
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"  # this tree's hdrcam, not the one .venv was installed from
out=${1:?usage: $0 OUT [--checkpoint CKPT] [--partner CKPT | --no-partner]}; shift
[ -d runs/data/val ] || { echo "runs/data is missing: python tools/split_hdr_train.py ../shared/data/hdr-train --out runs/data" >&2; exit 2; }
[ -e "$out" ] && { echo "$out exists: choose another OUT" >&2; exit 1; }
mkdir -p "$out"
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
for run in "val --data runs/data/val --size 512" "night --data procedural --count 16" \
           independent "train --data runs/data/train --size 512"; do
    read -r name words <<< "$run"
    read -ra args <<< "$words"
    if [ "$name" = independent ]; then  # generated first, their folder one word whatever OUT is called
        .venv/bin/python tools/independent_night_scenes.py --count 24 --seed 7 --out "$out/independent-scenes" \
            > "$out/independent-gen.log" 2>&1
        args=(--data "$out/independent-scenes" --size 512)
    fi
    started=$(date +%s.%N)
    .venv/bin/hdrcam evaluate "${args[@]}" "$@" --out "$out/$name" > "$out/$name.log" 2>&1
    echo "$name $(python3 -c "print(round($(date +%s.%N) - $started, 1))") s" >> "$out/seconds.txt"
    grep -E "^\| [^ ]+ \| [0-9]" "$out/$name/summary.md" | grep -vE "^\| (ldr|hdrcnn-blend|[^ ]+-network) \|" \
        | sed "s/^/$name: /" || true  # the checkpoints' full-pipeline rows
    if [ "$name" = independent ]; then rm -rf "$out/independent-scenes"; fi
done
started=$(date +%s.%N)
.venv/bin/python tools/bench_raw_path.py runs/data/val "$@" --out "$out/raw-path.md" > "$out/raw.log" 2>&1
echo "raw $(python3 -c "print(round($(date +%s.%N) - $started, 1))") s" >> "$out/seconds.txt"
grep '\*\*mean\*\*' "$out/raw-path.md" | sed "s/^/raw path: /"
