#!/usr/bin/env bash
# Fetch the Vulkan registry (vk.xml, validusage.json) shipped in Debian trixie's libvulkan-dev
# package and unpack it into DEST, without touching the system's apt configuration and without
# installing anything.
#
# usage: scripts/fetch-registry.sh [DEST]
#   DEST defaults to <repo>/target/registry/1.4.309
# After a successful run DEST/usr/share/vulkan/registry/{vk.xml,validusage.json} exist. DEST appears
# all at once (unpacked beside it, then renamed), and concurrent runs for the same DEST wait for each
# other, so a reader never sees a partial file.
set -euo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=lib/fetch.sh
source "$repo_root/scripts/lib/fetch.sh"

dest="${1:-$repo_root/target/registry/1.4.309}"
dest=$(realpath -m "$dest")
reg="usr/share/vulkan/registry"

if fetch_complete "$dest"; then
    echo "fetch-registry: already present in $dest/$reg"
    exit 0
fi
fetch_require apt-get dpkg dpkg-deb flock
fetch_lock "$dest"
if fetch_complete "$dest"; then
    echo "fetch-registry: already present in $dest/$reg (fetched by a concurrent run)"
    exit 0
fi

echo "fetch-registry: updating private package lists (trixie)"
fetch_apt_init trixie
echo "fetch-registry: downloading libvulkan-dev (trixie)"
fetch_debs "$fetch_apt_dir/debs" libvulkan-dev
deb="$(ls "$fetch_apt_dir"/debs/libvulkan-dev_*.deb 2>/dev/null | head -n1)"
[[ -n "$deb" ]] || { echo "fetch-registry: no .deb downloaded" >&2; exit 1; }

fetch_stage "$dest"
dpkg -x "$deb" "$FETCH_STAGE"
if [[ ! -s "$FETCH_STAGE/$reg/vk.xml" || ! -s "$FETCH_STAGE/$reg/validusage.json" ]]; then
    echo "fetch-registry: $(basename "$deb") lacks vk.xml or validusage.json" >&2
    exit 1
fi
fetch_commit "$FETCH_STAGE" "$dest"
echo "fetch-registry: unpacked $(basename "$deb") into $dest"
