#!/usr/bin/env bash
# The trainers' loop end to end: generate demos on one of our tasks, train robomimic's BC-RNN
# (low-dim) on them and roll the policy out in our simulator through robomimic's own scripts.
#   bash scripts/train_policy.sh TASK VARIANT [NUM_DEMOS] [-- TRAIN_POLICY_ARGS...]
#   bash scripts/train_policy.sh stack D1 1000 -- --epochs 50 --rollouts 50
# Set-up on first use: scripts/setup.sh, scripts/setup_learners.sh (robomimic, torch: about 6 GB)
# and the mimicgen_rs wheel (maturin, release build). Outputs in $OUT (default out/policy/TASK_VARIANT):
# the dataset, robomimic's run, result.json with the success rate. Seeds: generation 1, training
# 101 (the reference's), rollouts 1: the same command gives the same dataset and rollouts.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
if [ $# -lt 2 ] || [ "$1" = "-h" ] || [ "$1" = "--help" ]; then
  sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'
  exit $([ $# -lt 2 ] && [ "${1:-}" != "-h" ] && [ "${1:-}" != "--help" ] && echo 2 || echo 0)
fi
task="$1"; variant="$2"; shift 2
num=1000
if [ $# -gt 0 ] && [ "$1" != "--" ]; then num="$1"; shift; fi
[ "${1:-}" = "--" ] && shift
export MIMICGEN_CACHE="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$MIMICGEN_CACHE/target}"
export HDF5_USE_FILE_LOCKING=FALSE
out="${OUT:-out/policy/${task}_${variant}}"
mkdir -p "$out"
bash scripts/setup.sh
bash scripts/setup_learners.sh
python="$MIMICGEN_CACHE/venv-learners/bin/python"
# The wheel of this checkout (cargo builds only what changed since the last call).
wheels="$CARGO_TARGET_DIR/wheels-release"
rm -f "$wheels"/mimicgen_rs-*.whl
PATH="$MIMICGEN_CACHE/venv/bin:$PATH" maturin build --quiet --release --manifest-path app/python/Cargo.toml \
  --out "$wheels" --auditwheel repair
wheel="$(ls "$wheels"/mimicgen_rs-*.whl | head -1)"
"$MIMICGEN_CACHE/venv-learners/bin/pip" install -q --disable-pip-version-check --no-deps --force-reinstall "$wheel"
cargo build --release --quiet --bin mimicgen
dataset="$out/${task}_${variant}.hdf5"
[ -f "$dataset" ] || "$CARGO_TARGET_DIR/release/mimicgen" generate --task "$task" --variant "$variant" \
  --num-demos "$num" --guarantee --seed 1 --out "$dataset"
# The reference's rollout horizons (its generate_core_training_configs.py); 400 for the others.
case "$task" in
  three_piece_assembly|nut_assembly|mug_cleanup|hammer_cleanup) horizon=500 ;;
  coffee_preparation|kitchen) horizon=800 ;;
  pick_place) horizon=1000 ;;
  *) horizon=400 ;;
esac
"$python" scripts/train_policy.py "$dataset" "$out" --horizon "$horizon" "$@"
