#!/usr/bin/env bash
# Generation through our engine driving robosuite 1.4.1's own Stack environment (MuJoCo 2.3.2)
# from the reference's source demos: the wheel (built by scripts/test_python.sh) installed into
# the robosuite venv, then scripts/robosuite_generate.py with the arguments given
# (default: 50 attempts, seed 1, as BENCHMARKS.md reports).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
export MIMICGEN_CACHE="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$MIMICGEN_CACHE/target}"
export HDF5_USE_FILE_LOCKING=FALSE
bash scripts/setup_robosuite.sh
wheel="$(ls "$CARGO_TARGET_DIR"/wheels/mimicgen_rs-*.whl 2>/dev/null || true)"
[ -n "$wheel" ] || { bash scripts/test_python.sh >/dev/null; wheel="$(ls "$CARGO_TARGET_DIR"/wheels/mimicgen_rs-*.whl)"; }
venv="$MIMICGEN_CACHE/venv-robosuite"
"$venv/bin/pip" install -q --disable-pip-version-check --no-deps --force-reinstall "$wheel"
MUJOCO_GL=disable "$venv/bin/python" scripts/robosuite_generate.py "$@"
