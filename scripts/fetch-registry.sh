#!/usr/bin/env bash
# Fetch the Vulkan registry (vk.xml, validusage.json) shipped in Debian trixie's
# libvulkan-dev package and unpack it into DEST, without touching the system's apt
# configuration and without installing anything.
#
# usage: scripts/fetch-registry.sh [DEST]
#   DEST defaults to <repo>/target/registry/1.4.309
# After a successful run DEST/usr/share/vulkan/registry/{vk.xml,validusage.json} exist.
set -euo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
dest="${1:-$repo_root/target/registry/1.4.309}"
reg="$dest/usr/share/vulkan/registry"

if [[ -s "$reg/vk.xml" && -s "$reg/validusage.json" ]]; then
    echo "fetch-registry: already present in $reg"
    exit 0
fi

for tool in apt-get dpkg; do
    command -v "$tool" >/dev/null 2>&1 || { echo "fetch-registry: $tool not found" >&2; exit 2; }
done

tmp="$(mktemp -d "${TMPDIR:-/tmp}/fetch-registry.XXXXXX")"
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/lists/partial" "$tmp/archives/partial" "$tmp/cache"
mirror="${DEBIAN_MIRROR:-http://deb.debian.org/debian}"
keyring=/usr/share/keyrings/debian-archive-keyring.gpg
if [[ -r "$keyring" ]]; then
    echo "deb [signed-by=$keyring] $mirror trixie main" >"$tmp/sources.list"
else
    echo "deb $mirror trixie main" >"$tmp/sources.list"
fi

apt_opts=(
    -o "Dir::Etc::SourceList=$tmp/sources.list"
    -o "Dir::Etc::SourceParts=/dev/null"
    -o "Dir::State::Lists=$tmp/lists"
    -o "Dir::Cache::Archives=$tmp/archives"
    -o "Dir::Cache=$tmp/cache"
    -o "Dir::State::status=/var/lib/dpkg/status"
    -o "APT::Architecture=amd64"
    -o "Debug::NoLocking=1"
    -o "Acquire::Languages=none"
    -q
)

echo "fetch-registry: updating private package lists in $tmp"
apt-get "${apt_opts[@]}" update >"$tmp/update.log" 2>&1 || {
    cat "$tmp/update.log" >&2
    echo "fetch-registry: apt-get update failed" >&2
    exit 1
}
echo "fetch-registry: downloading libvulkan-dev (trixie)"
(cd "$tmp" && apt-get "${apt_opts[@]}" download libvulkan-dev >"$tmp/download.log" 2>&1) || {
    cat "$tmp/download.log" >&2
    echo "fetch-registry: apt-get download failed" >&2
    exit 1
}
deb="$(ls "$tmp"/libvulkan-dev_*.deb 2>/dev/null | head -n1)"
[[ -n "$deb" ]] || { echo "fetch-registry: no .deb downloaded" >&2; exit 1; }

mkdir -p "$dest"
dpkg -x "$deb" "$dest"
if [[ ! -s "$reg/vk.xml" || ! -s "$reg/validusage.json" ]]; then
    echo "fetch-registry: $(basename "$deb") lacks vk.xml or validusage.json" >&2
    exit 1
fi
echo "fetch-registry: unpacked $(basename "$deb") into $dest"
