#!/usr/bin/env bash
# One-time (idempotent) setup of a Python environment with LeRobot's dataset loader
# (lerobot-dataset 0.4.4, torch, pyarrow, PyAV) for scripts/check_lerobot.py. It lands in
# $MIMICGEN_CACHE/venv-lerobot (default ~/.cache/mimicgen); about 6 GB, most of it torch's CUDA
# libraries, which PyPI's torch wheel needs even on a machine without a GPU.
# A second call with unchanged requirements returns at once.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cache="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
mkdir -p "$cache"

venv="$cache/venv-lerobot"
stamp="$venv/.requirements.sha256"
want="$(sha256sum "$here/requirements-lerobot.txt" | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup_lerobot: creating Python environment in $venv (about 4 GB of wheels)"
  python3 -m venv --clear "$venv"
  # --no-cache-dir: the wheels are 4 GB; a copy in pip's cache would double that on disk.
  "$venv/bin/pip" install -q --disable-pip-version-check --no-cache-dir --no-deps --only-binary=:all: \
    -r "$here/requirements-lerobot.txt"
  "$venv/bin/python" -c 'import ledataset.datasets.lerobot_dataset, pyarrow, av; print("setup_lerobot: LeRobotDataset imports")'
  echo "$want" > "$stamp"
fi
