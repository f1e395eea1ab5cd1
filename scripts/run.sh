#!/usr/bin/env bash
# The project's run command (README): set-up, then the main job on the bundled default task.
# With no arguments and a display, it opens the app on the bundled Stack D0 source demos, with the
# Rerun viewer embedded (the `viewer` feature: its first build takes ~30 minutes on 2 cores);
# otherwise it runs the headless batch generation, and any arguments go to `mimicgen generate`
# (see `mimicgen generate --help`).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
export MIMICGEN_CACHE="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$MIMICGEN_CACHE/target}"
if [ $# -eq 0 ] && [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
  bash scripts/setup.sh --viewer
  echo "run.sh: opening the app (the first build with the embedded viewer takes a while)" >&2
  exec cargo run --release --quiet -p mimicgen-app --features viewer --bin mimicgen -- app
fi
bash scripts/setup.sh
[ $# -eq 0 ] && echo "run.sh: no display, so running the headless batch generation (mimicgen generate)" >&2
exec cargo run --release --quiet --bin mimicgen -- generate "$@"
