#!/usr/bin/env bash
# Builds the browser app (`mimicgen serve` serves it): the egui UI compiled to WebAssembly
# (crate mimicgen-web, release) and its JS glue made by wasm-bindgen, into $MIMICGEN_CACHE/web
# (default ~/.cache/mimicgen/web), where `mimicgen serve` looks for it from any directory.
# Installs what it needs, pinned: the rustup target wasm32-unknown-unknown and wasm-bindgen-cli
# 0.2.126 (exactly the wasm-bindgen of Cargo.lock) from crates.io, into the cache.
# Incremental: a second run with no change takes seconds.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
export MIMICGEN_CACHE="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$MIMICGEN_CACHE/target}"
bindgen_version=0.2.126
if ! rustup target list --installed 2>/dev/null | grep -qx wasm32-unknown-unknown; then
  echo "build_web: adding the rustup target wasm32-unknown-unknown"
  rustup target add wasm32-unknown-unknown >/dev/null
fi
bindgen="$MIMICGEN_CACHE/wasm-bindgen-$bindgen_version/bin/wasm-bindgen"
if [ ! -x "$bindgen" ]; then
  echo "build_web: installing wasm-bindgen-cli $bindgen_version (once, a few minutes)"
  cargo install -q wasm-bindgen-cli --version "$bindgen_version" --locked --root "$MIMICGEN_CACHE/wasm-bindgen-$bindgen_version"
fi
echo "build_web: cargo build -p mimicgen-web --target wasm32-unknown-unknown --release"
cargo build -q -p mimicgen-web --target wasm32-unknown-unknown --release
wasm="$CARGO_TARGET_DIR/wasm32-unknown-unknown/release/mimicgen_web.wasm"
out="$MIMICGEN_CACHE/web"
stamp="$(sha256sum "$wasm" | cut -d' ' -f1)"
if [ -f "$out/.stamp" ] && [ "$(cat "$out/.stamp")" = "$stamp" ]; then
  echo "build_web: $out is up to date"
  exit 0
fi
tmp="$(mktemp -d "$MIMICGEN_CACHE/web.XXXXXX")"
"$bindgen" --target web --no-typescript --out-dir "$tmp" --out-name mimicgen_web "$wasm"
gzip -k -9 "$tmp/mimicgen_web_bg.wasm" "$tmp/mimicgen_web.js"
echo "$stamp" > "$tmp/.stamp"
rm -rf "$out.old"
[ -d "$out" ] && mv "$out" "$out.old"
mv "$tmp" "$out"
rm -rf "$out.old"
echo "build_web: $out ($(du -h "$out/mimicgen_web_bg.wasm" | cut -f1) wasm, $(du -h "$out/mimicgen_web_bg.wasm.gz" | cut -f1) gzipped)"
