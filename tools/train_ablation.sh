#!/usr/bin/env bash
# The paper's Table 2 on our data: the same network preset and step budget behind a learned rank-1 DOE,
# a free-form DOE (Deep Optics), and the fixed dual-peak, 8-point star and Dirac PSFs; then one evaluation
# of all five on the same test set (once all five models exist).
# Usage: bash tools/train_ablation.sh [STEPS] [RUNS_DIR] [NAMES]   (NAMES: a comma list, default all five)
# Re-running continues interrupted runs (--resume) and skips finished ones. Two shells with different
# NAMES (and OMP_NUM_THREADS=1 each) share a 2-core machine best.
set -euo pipefail
steps="${1:-1000}"
runs="${2:-runs/ablation}"
names="${3:-rank1,dirac,star8,dual-peak,freeform}"
hdrcam="${HDRCAM:-.venv/bin/hdrcam}"
declare -A options=([rank1]="--doe rank1" [freeform]="--doe freeform" [dirac]="--psf dirac"
                    [star8]="--psf star8" [dual-peak]="--psf dual-peak")
for name in ${names//,/ }; do
  [[ -f "$runs/$name/model.pt" ]] && continue
  resume=()
  [[ -f "$runs/$name/config.json" ]] && resume=(--resume)  # a run claimed, saved or not
  # shellcheck disable=SC2086
  "$hdrcam" design --preset fast --steps "$steps" --seed 0 --out "$runs/$name" "${resume[@]}" ${options[$name]}
done
for name in rank1 freeform dual-peak star8 dirac; do
  [[ -f "$runs/$name/model.pt" ]] || exit 0
done
"$hdrcam" evaluate --size 512 --count 16 --out "$runs/evaluation" --overwrite \
  --checkpoint "rank1=$runs/rank1/model.pt" --checkpoint "freeform=$runs/freeform/model.pt" \
  --checkpoint "dual-peak=$runs/dual-peak/model.pt" --checkpoint "star8=$runs/star8/model.pt" \
  --checkpoint "dirac=$runs/dirac/model.pt"
