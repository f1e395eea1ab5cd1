#!/usr/bin/env bash
# One-time (idempotent) setup of everything the build and tests need beyond cargo:
#   - Debian: libhdf5-dev (the HDF5 C library our dataset crate links), pkg-config
#   - Python: a virtual environment with the pinned packages in scripts/requirements.txt
# Everything lands in $MIMICGEN_CACHE (default ~/.cache/mimicgen), outside the clone, so a fresh
# clone on the same machine reuses it.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cache="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
mkdir -p "$cache"

debian_packages=(libhdf5-dev=1.10.8+repack1-1 pkg-config)
missing=()
for p in "${debian_packages[@]}"; do
  name="${p%%=*}"
  dpkg-query -W -f='${Status}' "$name" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${missing[*]}"
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

venv="$cache/venv"
stamp="$venv/.requirements.sha256"
want="$(sha256sum "$here/requirements.txt" | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup: creating Python environment in $venv"
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q --disable-pip-version-check -r "$here/requirements.txt"
  echo "$want" > "$stamp"
fi
echo "setup: ok (cache $cache)"
