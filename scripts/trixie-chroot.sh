#!/usr/bin/env bash
# Run a command in a minimal Debian trixie root beside lavapipe, with trixie's 1.4.309 validation
# layer installed there (it needs glibc >= 2.38, which bookworm lacks). The root is made once with
# debootstrap and cached; the repository is bind-mounted at its own path, so a binary built here on
# bookworm (target/release/rtconf) runs there unchanged.
#
# usage: scripts/trixie-chroot.sh [--root DIR] [--] [CMD [ARG...]]
#   --root DIR   the cached root (default $RTCONF_TRIXIE_ROOT or /var/tmp/rtconf-trixie)
#   CMD          run in the repository's directory inside the root (default: an interactive bash);
#                with no CMD and no terminal, it only makes sure the root exists
# Inside: VK_DRIVER_FILES selects lavapipe (override by passing VK_DRIVER_FILES); VK_*, RTCONF_*
# and RUST_* variables of the caller pass through. The host's registry (/usr/share/vulkan/registry,
# 1.3.239) is mounted read-only at the same path, so `rtconf`'s default registry is bookworm's.
# Needs root (debootstrap, chroot, mounts); mounts live in a private mount namespace and vanish
# with the command. The root is built in a staging directory and renamed into place under a lock.
set -euo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=lib/fetch.sh
source "$repo_root/scripts/lib/fetch.sh"

root=${RTCONF_TRIXIE_ROOT:-/var/tmp/rtconf-trixie}
while [[ $# -gt 0 ]]; do
    case "$1" in
        --root) root=$2; shift 2 ;;
        --) shift; break ;;
        -h|--help) sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) break ;;
    esac
done
root=$(realpath -m "$root")
# What the root holds beyond minbase: lavapipe and the loader, the layer, glslang-tools (the harness
# links its compiler now; the package stays so an existing root still matches this list) and vulkaninfo (to report the layer's and the driver's versions).
packages=(mesa-vulkan-drivers libvulkan1 vulkan-validationlayers glslang-tools vulkan-tools ca-certificates)
wanted="${packages[*]}"

[[ "$(id -u)" -eq 0 ]] || { echo "trixie-chroot: needs root (debootstrap, chroot, mount)" >&2; exit 2; }

root_ready() {
    fetch_complete "$root" && [[ "$(cat "$root/.rtconf-packages" 2>/dev/null)" == "$wanted" ]]
}

if ! root_ready; then
    fetch_lock "$root"
    if ! root_ready; then
        if ! command -v debootstrap >/dev/null 2>&1; then
            echo "trixie-chroot: installing debootstrap (bookworm)" >&2
            DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -o DPkg::Lock::Timeout=600 debootstrap >&2
        fi
        mirror=${DEBIAN_MIRROR:-http://deb.debian.org/debian}
        fetch_stage "$root"
        echo "trixie-chroot: debootstrap trixie into $FETCH_STAGE (a few minutes)" >&2
        keyring=()
        [[ -r /usr/share/keyrings/debian-archive-keyring.gpg ]] &&
            keyring=(--keyring=/usr/share/keyrings/debian-archive-keyring.gpg)
        if ! debootstrap --variant=minbase "${keyring[@]}" \
                --include="$(IFS=,; echo "${packages[*]}")" \
                trixie "$FETCH_STAGE" "$mirror" >"$FETCH_STAGE.log" 2>&1; then
            tail -n 30 "$FETCH_STAGE.log" >&2
            [[ -f "$FETCH_STAGE/debootstrap/debootstrap.log" ]] && tail -n 30 "$FETCH_STAGE/debootstrap/debootstrap.log" >&2
            rm -f "$FETCH_STAGE.log"
            echo "trixie-chroot: debootstrap failed" >&2
            exit 1
        fi
        rm -f "$FETCH_STAGE.log"
        # debootstrap may leave its own mounts behind on failure paths; none may stay in the stage.
        if grep -qF " $FETCH_STAGE/" /proc/self/mountinfo; then
            echo "trixie-chroot: mounts left under $FETCH_STAGE" >&2
            exit 1
        fi
        rm -rf "$FETCH_STAGE"/var/cache/apt/archives/*.deb "$FETCH_STAGE"/var/lib/apt/lists/*_Packages
        mkdir -p "$FETCH_STAGE/usr/share/vulkan/registry"
        printf '%s\n' "$wanted" >"$FETCH_STAGE/.rtconf-packages"
        fetch_commit "$FETCH_STAGE" "$root"
        echo "trixie-chroot: root ready in $root" >&2
    fi
fi

if [[ $# -eq 0 && ! -t 0 ]]; then
    exit 0
fi
if [[ $# -eq 0 ]]; then
    set -- bash
fi

# Inside the root: the caller's directory when it lies in the repository, else the repository.
case "$PWD/" in
    "$repo_root"/*) workdir=$PWD ;;
    *) workdir=$repo_root ;;
esac
env_in=(
    HOME=/root
    PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
    LANG=C.UTF-8
    TERM="${TERM:-dumb}"
    VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.json
)
while IFS='=' read -r name _; do
    [[ "$name" =~ ^(VK_|RTCONF_|RUST_) ]] && env_in+=("$name=${!name}")
done < <(env)

inner=$(printf '%q ' "$@")
mount_and_run=$(cat <<EOF
set -e
mount -t proc proc $(printf %q "$root/proc")
mount --rbind /dev $(printf %q "$root/dev")
mount --rbind /sys $(printf %q "$root/sys")
mkdir -p $(printf %q "$root$repo_root")
mount --bind $(printf %q "$repo_root") $(printf %q "$root$repo_root")
if [ -d /usr/share/vulkan/registry ]; then
    mount --bind -o ro /usr/share/vulkan/registry $(printf %q "$root/usr/share/vulkan/registry")
fi
cp -L /etc/resolv.conf $(printf %q "$root/etc/resolv.conf") 2>/dev/null || true
exec chroot $(printf %q "$root") env -i $(printf '%q ' "${env_in[@]}") bash -c $(printf %q "cd $(printf %q "$workdir") && exec $inner")
EOF
)
exec unshare --mount --propagation private -- bash -c "$mount_and_run"
