#!/usr/bin/env bash
# Do no harm beyond the drawn crops: `hdrcam evaluate` seeds each photograph's test crop by its file name, so the
# same files linked under other names (NAME--vK.ext) give other crops under the same protocol. Links the
# development photographs (runs/data/train and ../shared/data/hdr; never the validation split) as variants K,
# evaluates each (default pair, one thread, about a minute per variant; extra options go to evaluate, e.g.
# --psf runs/dirac-psf/psf.exr) and prints per variant the mean gain over the LDR capture, the worst image and
# every image more than 0.03 dB below its capture. Records: tools/results/real-data/stress-crops.
# Usage: bash tools/stress_crops.sh OUT K1 K2 ... [-- EVALUATE OPTIONS]
set -euo pipefail
cd "$(dirname "$0")/.."
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"  # this tree's hdrcam, not the one .venv was installed from
[ $# -ge 1 ] || { echo "usage: $0 OUT K1 K2 ... [-- EVALUATE OPTIONS]" >&2; exit 2; }
out=$1; shift
[ -d runs/data/train ] || { echo "runs/data is missing: python tools/split_hdr_train.py ../shared/data/hdr-train --out runs/data" >&2; exit 2; }
[ -e "$out" ] && { echo "$out exists: choose another OUT" >&2; exit 1; }
variants=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do variants+=("$1"); shift; done
[ $# -gt 0 ] && shift
[ ${#variants[@]} -gt 0 ] || { echo "name at least one variant K" >&2; exit 2; }
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
for k in "${variants[@]}"; do
  mkdir -p "$out/links-v$k"
  for f in runs/data/train/* ../shared/data/hdr/*.exr; do
    b=$(basename "$f"); ln -s "$(realpath "$f")" "$out/links-v$k/${b%.*}--v$k.${b##*.}"
  done
  .venv/bin/hdrcam evaluate --data "$out/links-v$k" --size 512 "$@" --out "$out/v$k" > "$out/v$k.log" 2>&1
  python3 - "$out/v$k/metrics.csv" "v$k" <<'PY'
import csv, sys
psnr = {(row["image"], row["method"]): float(row["psnr_linear"]) for row in csv.DictReader(open(sys.argv[1]))}
gains = {image: psnr[(image, "hdrcam")] - psnr[(image, "ldr")] for image, method in psnr if method == "hdrcam"}
worst = min(gains, key=gains.get)
below = ", ".join(f"{image} {gain:+.2f}" for image, gain in sorted(gains.items()) if gain < -0.03) or "none"
print(f"{sys.argv[2]}: {len(gains)} crops, mean {sum(gains.values()) / len(gains):+.3f} dB, worst {gains[worst]:+.3f} "
      f"({worst}); below -0.03 dB: {below}")
PY
done
