#!/usr/bin/env bash
# The project's run command (README): set-up, then the main job on the bundled default task.
#   ./scripts/run.sh                    with a display: the app on the bundled Stack D0 source demos
#                                       (its "3D view" starts the viewer of the rerun-sdk wheel);
#                                       without one: the headless batch generation
#   ./scripts/run.sh ARGS...            `mimicgen generate ARGS` (see `mimicgen generate --help`)
#   ./scripts/run.sh serve [ARGS...]    the app for a browser (`mimicgen serve --help`; builds the
#                                       WebAssembly bundle first, no display needed)
#   ./scripts/run.sh --embedded-viewer  the app with the Rerun viewer inside its window (cargo
#                                       feature `viewer`: its first build takes 30-50 minutes on 2 cores)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
export MIMICGEN_CACHE="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$MIMICGEN_CACHE/target}"
if [ "${1:-}" = "serve" ]; then
  shift
  bash scripts/setup.sh
  bash scripts/build_web.sh
  # With no arguments: the bundled Stack D0 source demos, files under this clone.
  [ $# -eq 0 ] && set -- core/sim/data/stack_D0_source.hdf5
  exec cargo run --release --quiet --bin mimicgen -- serve "$@"
fi
if [ "${1:-}" = "--embedded-viewer" ]; then
  shift
  bash scripts/setup.sh --viewer
  echo "run.sh: opening the app with the viewer embedded (its first build takes 30-50 minutes)" >&2
  exec cargo run --release --quiet -p mimicgen-app --features viewer --bin mimicgen -- app "$@"
fi
if [ $# -eq 0 ] && [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
  bash scripts/setup.sh
  echo "run.sh: opening the app (./scripts/run.sh --embedded-viewer puts the 3D view inside its window)" >&2
  exec cargo run --release --quiet --bin mimicgen -- app
fi
bash scripts/setup.sh
[ $# -eq 0 ] && echo "run.sh: no display, so running the headless batch generation (mimicgen generate)" >&2
exec cargo run --release --quiet --bin mimicgen -- generate "$@"
