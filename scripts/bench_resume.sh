#!/usr/bin/env bash
# Kill a `mimicgen generate` run with SIGKILL at random points, resume it each time, and check that
# the finished dataset equals an uninterrupted run of the same command (same demos from the same
# attempts, bit-identical arrays; scripts/compare_datasets.py).
#
#   scripts/bench_resume.sh [KILLS] [ATTEMPTS] [WORKERS]      (defaults 20, 1000, 2)
#
# The kill times are drawn with a fixed seed, spread over the uninterrupted run's wall time.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
kills="${1:-20}" attempts="${2:-1000}" workers="${3:-2}"
export MIMICGEN_CACHE="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$MIMICGEN_CACHE/target}"
export HDF5_USE_FILE_LOCKING=FALSE
cargo build --release --quiet --bin mimicgen
bin="$CARGO_TARGET_DIR/release/mimicgen"
dir="$(mktemp -d)"
trap 'rm -rf "$dir"' EXIT
args=(generate --num-demos "$attempts" --seed 1 --workers "$workers" --keep-failed)
start=$(date +%s.%N)
"$bin" "${args[@]}" --out "$dir/whole.hdf5" >/dev/null 2>&1
whole_s=$(echo "$(date +%s.%N) - $start" | bc)
echo "uninterrupted: ${whole_s} s"
RANDOM=7
done_kills=0 sessions=0
start=$(date +%s.%N)
while [ ! -f "$dir/pieces.hdf5" ]; do
  extra=()
  [ -f "$dir/pieces.hdf5.partial" ] && extra=(--resume)
  "$bin" "${args[@]}" --out "$dir/pieces.hdf5" "${extra[@]}" >/dev/null 2>"$dir/err" &
  pid=$!
  sessions=$((sessions + 1))
  if [ "$done_kills" -lt "$kills" ]; then
    # A random point within the share of the run left to each remaining kill (at least 0.5 s).
    share=$(echo "scale=3; $whole_s / ($kills + 1)" | bc)
    delay=$(echo "scale=3; 0.5 + $share * ($RANDOM % 1000) / 500" | bc)
    sleep "$delay"
    if kill -0 "$pid" 2>/dev/null; then
      kill -9 "$pid"; wait "$pid" 2>/dev/null || true
      done_kills=$((done_kills + 1))
      continue
    fi
  fi
  wait "$pid" || { cat "$dir/err"; exit 1; }
done
pieces_s=$(echo "$(date +%s.%N) - $start" | bc)
echo "killed $done_kills times over $sessions sessions: ${pieces_s} s in all"
for f in pieces pieces_failed; do
  w="${f/pieces/whole}"
  "$MIMICGEN_CACHE/venv/bin/python" scripts/compare_datasets.py "$dir/$w.hdf5" "$dir/$f.hdf5" | tail -2
done
