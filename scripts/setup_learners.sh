#!/usr/bin/env bash
# One-time (idempotent) setup of a Python environment with the learners' tools
# (scripts/requirements-learners.txt: LeRobot's dataset loader, robomimic 0.3.0, gymnasium, torch)
# for scripts/check_lerobot.py and scripts/train_policy.py. It lands in
# $MIMICGEN_CACHE/venv-learners (default ~/.cache/mimicgen); about 6 GB, most of it torch's CUDA
# libraries, which PyPI's torch wheel needs even on a machine without a GPU.
# A second call with unchanged requirements returns at once. Our own package (mimicgen_rs) is
# installed over it by the scripts that need it, from the wheel scripts/test_python.sh builds.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cache="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
mkdir -p "$cache"

venv="$cache/venv-learners"
stamp="$venv/.requirements.sha256"
want="$(sha256sum "$here/requirements-learners.txt" | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup_learners: creating Python environment in $venv (about 4 GB of wheels)"
  python3 -m venv --clear "$venv"
  wheels="$(mktemp)"
  trap 'rm -f "$wheels"' EXIT
  grep -v '^robomimic==' "$here/requirements-learners.txt" > "$wheels"
  # --no-cache-dir: the wheels are 4 GB; a copy in pip's cache would double that on disk.
  "$venv/bin/pip" install -q --disable-pip-version-check --no-cache-dir --no-deps --only-binary=:all: -r "$wheels"
  # robomimic's one release on PyPI is a source archive: built here with the pinned setuptools.
  "$venv/bin/pip" install -q --disable-pip-version-check --no-cache-dir --no-deps --no-build-isolation \
    "$(grep '^robomimic==' "$here/requirements-learners.txt")"
  "$venv/bin/python" -c 'import ledataset.datasets.lerobot_dataset, lerobot.datasets.lerobot_dataset, pyarrow, av, gymnasium, robomimic.scripts.train, robomimic.scripts.run_trained_agent; print("setup_learners: LeRobotDataset, robomimic and gymnasium import")'
  echo "$want" > "$stamp"
fi
