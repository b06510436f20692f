#!/usr/bin/env bash
# Alternate test crops of photographs: `hdrcam evaluate` seeds each photograph's crop by its file name, so the
# same files linked under other names (NAME--vK.ext) give other crops under the same protocol.
# Usage: bash make_variants.sh OUT K1 K2 ... -- FILE...   (writes OUT/vK/NAME--vK.ext symlinks)
set -euo pipefail
out=$1; shift
variants=()
while [ "$1" != "--" ]; do variants+=("$1"); shift; done; shift
for k in "${variants[@]}"; do
  mkdir -p "$out/v$k"
  for f in "$@"; do
    b=$(basename "$f"); ln -sfn "$(realpath "$f")" "$out/v$k/${b%.*}--v$k.${b##*.}"
  done
done
