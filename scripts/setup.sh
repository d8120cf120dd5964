#!/usr/bin/env bash
# rtconf set-up: installs what the conformance run and the tests need on Debian 12 (bookworm).
# Idempotent: does nothing when everything is already present. Never adds trixie or sid.
# Concurrent runs are serialised under a lock; the backports list appears whole (written, then renamed).
set -euo pipefail

need=()
have_pkg() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q 'install ok installed'; }

lvp_icd=/usr/share/vulkan/icd.d/lvp_icd.json
lavapipe_ok() {
  # bookworm's own Mesa (22.3) has no ray tracing; we need the backports one (>= 25).
  have_pkg mesa-vulkan-drivers || return 1
  local v
  v=$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers)
  dpkg --compare-versions "$v" ge 24 && [ -f "$lvp_icd" ]
}

missing() {
  need=()
  # ca-certificates: cargo fetches the crates over https; chromium: the HTML report's browser test;
  # libshaderc-dev: the shader compiler the harness links (with glslang-dev's and spirv-tools' archives).
  for p in libvulkan1 libvulkan-dev vulkan-validationlayers glslang-tools libshaderc-dev vulkan-tools ca-certificates chromium; do
    have_pkg "$p" || need+=("$p")
  done
  # rustc links through the system C compiler (`cc`); a Debian with only rustup has none.
  command -v cc >/dev/null 2>&1 || need+=(gcc libc6-dev)
  [ ${#need[@]} -gt 0 ] || ! lavapipe_ok
}

missing || exit 0

if [ "$(id -u)" -ne 0 ]; then
  SUDO=sudo
else
  SUDO=
fi

lock=/var/lock/rtconf-setup.lock
[ -w /var/lock ] || lock=${TMPDIR:-/tmp}/rtconf-setup.lock
exec 9>"$lock"
flock -w 1800 9 || { echo "rtconf setup: timed out waiting for $lock" >&2; exit 1; }
missing || exit 0   # a concurrent run installed it meanwhile

codename=$(. /etc/os-release && echo "${VERSION_CODENAME:-}")
if [ "$codename" != "bookworm" ]; then
  echo "rtconf setup: this script targets Debian 12 (bookworm); found '${codename:-unknown}'." >&2
  echo "Install by hand: Mesa >= 24 lavapipe with ray tracing, libvulkan-dev, vulkan-validationlayers, glslang-tools, libshaderc-dev, chromium." >&2
  exit 1
fi

# The backports suite, written with the same mirror the machine already uses.
bp=/etc/apt/sources.list.d/rtconf-bookworm-backports.list
if ! grep -rqs 'bookworm-backports' /etc/apt/sources.list /etc/apt/sources.list.d/; then
  # The first non-security mirror of an active line: deb822 "URIs:" or one-line "deb URL".
  mirror=$(cat /etc/apt/sources.list /etc/apt/sources.list.d/*.list /etc/apt/sources.list.d/*.sources 2>/dev/null \
           | grep -E '^(URIs:|deb )' | grep -oE 'https?://[^ ]+' | grep -v security | head -n1 || true)
  mirror=${mirror:-http://deb.debian.org/debian}
  echo "deb ${mirror%/} bookworm-backports main" | $SUDO tee "$bp.rtconf-new" >/dev/null
  $SUDO mv -f "$bp.rtconf-new" "$bp"
fi

export DEBIAN_FRONTEND=noninteractive
apt_opts=(-o DPkg::Lock::Timeout=600)
$SUDO apt-get "${apt_opts[@]}" update -qq
lavapipe_ok || $SUDO apt-get "${apt_opts[@]}" install -y -qq -t bookworm-backports mesa-vulkan-drivers
if [ ${#need[@]} -gt 0 ]; then
  $SUDO apt-get "${apt_opts[@]}" install -y -qq "${need[@]}"
fi
lavapipe_ok || { echo "rtconf setup: lavapipe with ray tracing is still missing after install" >&2; exit 1; }
echo "rtconf setup: done"
