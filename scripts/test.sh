#!/usr/bin/env bash
# The project's test command (README, .ci/run): set-up, then formatting, lints, docs and every test.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh
export MIMICGEN_CACHE="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
export MIMICGEN_PYTHON="${MIMICGEN_PYTHON:-$MIMICGEN_CACHE/venv/bin/python}"
# Build outputs live outside the clone, so a fresh clone on the same machine builds incrementally.
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$MIMICGEN_CACHE/target}"
# libhdf5 locks files without close-on-exec, so a child process can keep a test's file locked.
export HDF5_USE_FILE_LOCKING=FALSE
echo "== cargo fmt --check"; cargo fmt --all --check
echo "== cargo clippy";      cargo clippy --workspace --all-targets --quiet -- -D warnings
echo "== cargo doc";         RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --quiet
echo "== cargo test";        cargo test --workspace
