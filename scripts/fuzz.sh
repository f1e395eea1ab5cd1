#!/usr/bin/env bash
# Fuzzes our readers with cargo-fuzz (libFuzzer): the TOML spec reader, MimicGen JSON configs, a
# tab's WebSocket messages to `mimicgen serve` (client_message),
# task files, and the HDF5 dataset reader on mutated copies of the bundled source demos. Each
# target runs for SECONDS (default 300) on all cores but one; new inputs that reach new code are
# merged into fuzz/corpus/<target>/ (minimised), crashes land in fuzz/artifacts/<target>/. Both are
# replayed by tests/tests/fuzz_corpus.rs in CI (cargo test), which needs none of this.
#   bash scripts/fuzz.sh                 # every target, 5 minutes each
#   bash scripts/fuzz.sh 60 spec_toml    # one target, one minute
# dataset_bytes edits an HDF5 file's bytes, so it reaches libhdf5's C parser: a crash there (an
# AddressSanitizer report or SEGV with libhdf5 frames) cannot be replayed in CI without killing the
# test process; move such a reproducer to fuzz/known_crashes/<target>/ with a line in its README.
# cargo-fuzz needs nightly flags: RUSTC_BOOTSTRAP=1 lets the pinned stable toolchain take them.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
seconds="${1:-300}"
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(spec_toml spec_json task_file dataset dataset_bytes client_message)
export RUSTC_BOOTSTRAP=1
export CARGO_TARGET_DIR="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}/fuzz-target"
if ! cargo fuzz --version 2>/dev/null | grep -q "0.13.1"; then
  cargo install cargo-fuzz --version 0.13.1 --locked
fi
jobs=$(( $(nproc) > 1 ? $(nproc) - 1 : 1 ))
# The dataset target writes a scratch HDF5 file per input: in memory where the machine has tmpfs.
[ -z "${TMPDIR:-}" ] && [ -d /dev/shm ] && [ -w /dev/shm ] && export TMPDIR=/dev/shm
for t in "${targets[@]}"; do
  mkdir -p "fuzz/corpus/$t" "fuzz/artifacts/$t"
  new="$(mktemp -d)"
  echo "fuzz: $t for ${seconds}s on $jobs job(s)"
  # -fork keeps going after a crash (each is saved); the new corpus is merged in minimised.
  cargo fuzz run --fuzz-dir fuzz "$t" "$new" "fuzz/corpus/$t" -- \
    -max_total_time="$seconds" -fork="$jobs" -ignore_crashes=1 -ignore_timeouts=1 -timeout=60 -max_len=4096 -rss_limit_mb=4096 \
    -artifact_prefix="fuzz/artifacts/$t/" 2>&1 | grep -E "^#|INFO: fuzzed|CRASH|panicked|ERROR|stat::" | tail -n 20 || true
  merged="$(mktemp -d)"
  cargo fuzz run --fuzz-dir fuzz "$t" "$merged" "fuzz/corpus/$t" "$new" -- -merge=1 2>&1 | grep -E "MERGE-OUTER: [0-9]+ new files" || true
  rm -rf "fuzz/corpus/$t" && mv "$merged" "fuzz/corpus/$t" && rm -rf "$new"
  echo "fuzz: $t corpus $(ls "fuzz/corpus/$t" | wc -l) inputs, $(ls "fuzz/artifacts/$t" | wc -l) crash reproducers"
done
