#!/usr/bin/env bash
# The browser app's tests: `mimicgen serve` driven in Debian's headless chromium by Playwright
# (tests/web/app.test.mjs: annotate, save, the file browser, the 3D view and its time cursor, a
# run, a failed attempt side by side, a run that survives its tab). Installs what it needs,
# pinned: Debian's chromium and fonts-liberation (scripts/debian_pins.sh), playwright-core from tests/web/package-lock.json;
# builds the WebAssembly bundle (scripts/build_web.sh) and the mimicgen binary (unless MIMICGEN_BIN
# names one already built, as scripts/test.sh does).
#   bash scripts/test_web.sh                     # as CI runs it (scripts/test.sh)
#   MIMICGEN_WEB_SHOTS=docs/img bash scripts/test_web.sh   # also writes the docs' screenshots
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
export MIMICGEN_CACHE="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$MIMICGEN_CACHE/target}"
# shellcheck source=debian_pins.sh
source scripts/debian_pins.sh
install_pinned test_web "${DEBIAN_WEB_PINS[@]}"
if [ ! -d tests/web/node_modules/playwright-core ]; then
  echo "test_web: npm ci (playwright-core, no browser download)"
  (cd tests/web && PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 npm ci --silent --no-audit --no-fund)
fi
bash scripts/build_web.sh
if [ -z "${MIMICGEN_BIN:-}" ]; then
  cargo build -q --bin mimicgen
  MIMICGEN_BIN="$CARGO_TARGET_DIR/debug/mimicgen"
fi
[ -x "$MIMICGEN_BIN" ] || { echo "test_web: no mimicgen binary at $MIMICGEN_BIN" >&2; exit 1; }
[ -n "${MIMICGEN_WEB_SHOTS:-}" ] && mkdir -p "$MIMICGEN_WEB_SHOTS"
MIMICGEN_BIN="$MIMICGEN_BIN" CHROMIUM=/usr/bin/chromium node --test tests/web/
