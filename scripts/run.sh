#!/usr/bin/env bash
# The project's run command (README): set-up, then generation on the bundled default task.
# Any arguments are passed to `mimicgen generate` (see `mimicgen generate --help`).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh
export MIMICGEN_CACHE="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$MIMICGEN_CACHE/target}"
exec cargo run --release --quiet --bin mimicgen -- generate "$@"
