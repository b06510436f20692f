#!/usr/bin/env bash
# Create .venv (if missing) and install hdrcam with its test extras into it.
# torch: an environment that already has torch keeps it (CPU or CUDA build). Otherwise the pinned
# HDRCAM_TORCH_SPEC is installed first; on the project's machines torch==2.13.0 is a CPU wheel on
# local disk, elsewhere pip takes that release's default build for the platform.
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${HDRCAM_VENV:-.venv}"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
py="$venv/bin/python"
if ! "$py" -c "import torch" 2>/dev/null; then
    "$py" -m pip install --quiet "${HDRCAM_TORCH_SPEC:-torch==2.13.0}"
fi
"$py" -m pip install --quiet -e ".[test]"
"$py" -c "import hdrcam, torch; print(f'hdrcam {hdrcam.__version__} ready in $venv (torch {torch.__version__})')"
