#!/usr/bin/env bash
# Fetch the 1.4.309 Khronos validation layer (Debian trixie's vulkan-validationlayers) with the
# libstdc++6 and libgcc-s1 it needs, and unpack them into DEST without installing anything or
# touching the machine's apt sources. The layer needs glibc >= 2.38: it loads on trixie and on
# Ubuntu 24.04, not on bookworm (2.36); run it here through scripts/trixie-chroot.sh.
#
# usage: scripts/layer-1.4.309.sh [--with-registry] [--debs DIR] [DEST]
#   DEST defaults to <repo>/target/layers/1.4.309
#   --with-registry  also trixie's libvulkan-dev: the 1.4.309 registry in DEST/usr/share/vulkan/registry
#                    (the layer's own version, for `rtconf run --from`)
#   --debs DIR       also keep the .deb files in DIR (atomically, like DEST)
# Prints the two variables that select the layer:
#   VK_LAYER_PATH=DEST/usr/share/vulkan/explicit_layer.d
#   LD_LIBRARY_PATH=DEST/usr/lib/x86_64-linux-gnu
set -euo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=lib/fetch.sh
source "$repo_root/scripts/lib/fetch.sh"

debs_out=
packages=(vulkan-validationlayers libstdc++6 libgcc-s1)
while [[ $# -gt 0 ]]; do
    case "$1" in
        --debs) debs_out=$(realpath -m "$2"); shift 2 ;;
        --with-registry) packages+=(libvulkan-dev); shift ;;
        -h|--help) sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        -*) echo "layer-1.4.309: unknown option $1" >&2; exit 2 ;;
        *) break ;;
    esac
done
dest=$(realpath -m "${1:-$repo_root/target/layers/1.4.309}")
version=1.4.309
manifest=usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
libdir=usr/lib/x86_64-linux-gnu

print_env() {
    echo "VK_LAYER_PATH=$dest/usr/share/vulkan/explicit_layer.d"
    echo "LD_LIBRARY_PATH=$dest/$libdir"
}

# Complete, and holding every package asked for this time (one made without the registry is made
# again when the registry is asked for).
have() {
    fetch_complete "$1" || return 1
    local held p
    held=" $(cat "$1/.rtconf-packages" 2>/dev/null) "
    for p in "${packages[@]}"; do
        [[ "$held" == *" $p "* ]] || return 1
    done
}

if have "$dest" && { [[ -z "$debs_out" ]] || have "$debs_out"; }; then
    echo "layer-1.4.309: already present in $dest" >&2
    print_env
    exit 0
fi
fetch_require apt-get dpkg dpkg-deb flock
fetch_lock "$dest"
[[ -n "$debs_out" ]] && fetch_lock "$debs_out"

if ! have "$dest" || { [[ -n "$debs_out" ]] && ! have "$debs_out"; }; then
    echo "layer-1.4.309: updating private package lists (trixie)" >&2
    fetch_apt_init trixie
    echo "layer-1.4.309: downloading ${packages[*]} (trixie)" >&2
    fetch_debs "$fetch_apt_dir/debs" "${packages[@]}"
    layer_deb=$(ls "$fetch_apt_dir"/debs/vulkan-validationlayers_*.deb)
    got=$(fetch_deb_version "$layer_deb")
    if [[ "$got" != "$version".* ]]; then
        echo "layer-1.4.309: trixie now ships vulkan-validationlayers $got, not $version" >&2
        exit 1
    fi
    if ! have "$dest"; then
        fetch_stage "$dest"
        for deb in "$fetch_apt_dir"/debs/*.deb; do
            dpkg -x "$deb" "$FETCH_STAGE"
        done
        [[ -s "$FETCH_STAGE/$manifest" && -e "$FETCH_STAGE/$libdir/libVkLayer_khronos_validation.so" ]] || {
            echo "layer-1.4.309: the unpacked packages lack the layer's manifest or library" >&2
            exit 1
        }
        printf '%s\n' "${packages[*]}" >"$FETCH_STAGE/.rtconf-packages"
        fetch_commit "$FETCH_STAGE" "$dest"
        echo "layer-1.4.309: unpacked vulkan-validationlayers $got into $dest" >&2
    fi
    if [[ -n "$debs_out" ]] && ! have "$debs_out"; then
        fetch_stage "$debs_out"
        cp "$fetch_apt_dir"/debs/*.deb "$FETCH_STAGE/"
        printf '%s\n' "${packages[*]}" >"$FETCH_STAGE/.rtconf-packages"
        fetch_commit "$FETCH_STAGE" "$debs_out"
        echo "layer-1.4.309: kept the .debs in $debs_out" >&2
    fi
fi
print_env
