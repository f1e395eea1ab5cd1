#!/usr/bin/env bash
# Debian packages at pinned versions, for scripts/setup.sh and scripts/test_web.sh (sourced), and
# the check scripts/test.sh runs (executed: `bash scripts/debian_pins.sh --check`).
#
# Debian's archive keeps one version of a package per suite: bookworm's main suite changes only at
# a point release, bookworm-security with every security update (chromium's every few weeks). So
# each pin names the version bookworm's main suite holds, and a pin that no longer holds is never
# silent: `install_pinned` installs the archive's version instead with a banner in the log, and
# `--check` lists every pin the archive has dropped (a warning, not a failure: a security update
# must not fail a user's test run; update the pin then).
set -euo pipefail

# Every Debian package the project installs, pinned. setup.sh: the build (HDF5), offscreen
# rendering (EGL with Mesa's software renderer), two-host Ray tests (iproute2); --viewer adds
# libudev-dev. test_web.sh: the headless browser and its fonts.
DEBIAN_SETUP_PINS=(libhdf5-dev=1.10.8+repack1-1 pkg-config=1.8.1-1
  libegl1=1.6.0-1 libegl-mesa0=22.3.6-1+deb12u2 libgl1-mesa-dri=22.3.6-1+deb12u2 libgl1=1.6.0-1
  iproute2=6.1.0-3)
DEBIAN_VIEWER_PINS=(libudev-dev=252.39-1~deb12u2)
# chromium-common must be pinned beside chromium: apt takes the newest of a package left unpinned.
DEBIAN_WEB_PINS=(chromium=150.0.7871.100-1~deb12u1 chromium-common=150.0.7871.100-1~deb12u1 fonts-liberation=1:1.07.4-11)

pins_banner() { # lines...
  {
    echo "################################################################################"
    printf '# %s\n' "$@"
    echo "################################################################################"
  } >&2
}

pins_apt() {
  if [ "$(id -u)" -ne 0 ]; then sudo "$@"; else "$@"; fi
}

# The versions of NAME that the archive offers (after `apt-get update`), one a line.
archive_versions() {
  apt-cache madison "$1" 2>/dev/null | awk -F'|' '{gsub(/ /, "", $2); print $2}'
}

# install_pinned WHO NAME=VERSION...: installs the packages not yet installed, at their pinned
# versions where the archive has them; says loudly which it had to take at another version.
install_pinned() {
  local who="$1"; shift
  local p name version installed missing=() pinned=() floating=()
  for p in "$@"; do
    name="${p%%=*}" version="${p#*=}"
    installed="$(dpkg-query -W -f='${Status} ${Version}' "$name" 2>/dev/null || true)"
    case "$installed" in
      "install ok installed $version") ;;
      "install ok installed "*) echo "$who: $name ${installed##* } is installed (pinned: $version); keeping it" >&2 ;;
      *) missing+=("$p") ;;
    esac
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "$who: installing Debian packages: ${missing[*]}"
  pins_apt apt-get update -qq
  for p in "${missing[@]}"; do
    name="${p%%=*}" version="${p#*=}"
    if archive_versions "$name" | grep -qxF "$version"; then
      pinned+=("$p")
    else
      floating+=("$name")
      pins_banner "$who: PIN NOT HELD: $name=$version is no longer in Debian's archive" \
        "(it has: $(archive_versions "$name" | paste -sd' ' || true)); installing the archive's candidate." \
        "Update the pin in scripts/debian_pins.sh."
    fi
  done
  export DEBIAN_FRONTEND=noninteractive
  if [ ${#pinned[@]} -gt 0 ] && ! pins_apt apt-get install -y -qq --no-install-recommends "${pinned[@]}" >/dev/null; then
    pins_banner "$who: PIN NOT HELD: apt could not install ${pinned[*]} together" \
      "(a dependency the pins do not name moved on); installing the archive's candidates." \
      "Update the pins in scripts/debian_pins.sh."
    floating+=("${pinned[@]%%=*}")
  fi
  [ ${#floating[@]} -eq 0 ] || pins_apt apt-get install -y -qq --no-install-recommends "${floating[@]}" >/dev/null
}

# Every pin checked against the archive as it is today; prints one line per pin, returns 0.
check_pins() {
  local p name version dropped=()
  pins_apt apt-get update -qq || { echo "debian pins: apt-get update failed; pins not checked" >&2; return 0; }
  for p in "${DEBIAN_SETUP_PINS[@]}" "${DEBIAN_VIEWER_PINS[@]}" "${DEBIAN_WEB_PINS[@]}"; do
    name="${p%%=*}" version="${p#*=}"
    if archive_versions "$name" | grep -qxF "$version"; then
      echo "debian pins: $p in the archive"
    else
      dropped+=("$p (the archive has: $(archive_versions "$name" | paste -sd' ' || true))")
    fi
  done
  if [ ${#dropped[@]} -gt 0 ]; then
    pins_banner "debian pins: PINS NOT HELD: a fresh machine would install other versions of:" "${dropped[@]}" \
      "Update them in scripts/debian_pins.sh."
  fi
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
  case "${1:-}" in
    --check) check_pins ;;
    *) echo "usage: bash scripts/debian_pins.sh --check (or source it and call install_pinned)" >&2; exit 2 ;;
  esac
fi
