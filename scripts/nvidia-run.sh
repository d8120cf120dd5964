#!/usr/bin/env bash
# On the NVIDIA machine (Ubuntu 24.04, no Vulkan loader, layer, glslang or network): put the
# carried bundle of scripts/nvidia-bundle.sh in place and run one `rtconf` command on NVIDIA's
# driver under the chosen validation layer.
#
# usage: scripts/nvidia-run.sh [--layer 1.3.239|1.4.309] [--] RTCONF-ARGS...
#   --layer 1.3.239  (default) bookworm's layer from .gl/debs, unpacked into /
#   --layer 1.4.309  trixie's layer from .gl-1.4.309/debs, unpacked into target/layers/1.4.309-carried
#                    and selected with VK_LAYER_PATH + LD_LIBRARY_PATH; a `run`, `stress`, `replay` or
#                    `detect` without --from gets --from with that layer's own registry (1.4.309)
# example:
#   bash scripts/nvidia-run.sh --layer 1.4.309 run --driver nvidia --profile nvidia-h100 --out out/nvidia-1.4.309
#   bash scripts/nvidia-run.sh stress --driver nvidia --profile nvidia-h200 --out out/nvidia-stress
# Environment:
#   RTCONF_BIN       the binary (default .gl/bin/rtconf, else target/release/rtconf)
#   VK_DRIVER_FILES  the ICD (default NVIDIA's /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json;
#                    note that `rtconf --driver` sets it again for the run itself)
#   RTCONF_PREFIX    where the bookworm debs unpack (default /; ldconfig runs when it is /)
# The bookworm debs unpack once (a stamp records which) under a lock; the 1.4.309 folder appears
# whole (staged beside it, then renamed).
set -euo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=lib/fetch.sh
source "$repo_root/scripts/lib/fetch.sh"

layer=1.3.239
while [[ $# -gt 0 ]]; do
    case "$1" in
        --layer) layer=$2; shift 2 ;;
        --) shift; break ;;
        -h|--help) sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) break ;;
    esac
done
[[ $# -gt 0 ]] || { echo "nvidia-run: give an rtconf command (see --help)" >&2; exit 2; }
[[ "$layer" == 1.3.239 || "$layer" == 1.4.309 ]] || { echo "nvidia-run: --layer 1.3.239 or 1.4.309" >&2; exit 2; }

bookworm_debs="$repo_root/.gl/debs"
trixie_debs="$repo_root/.gl-1.4.309/debs"
prefix=$(realpath -m "${RTCONF_PREFIX:-/}")
root=${prefix%/}   # "" for /, so paths read /usr/... rather than //usr/...
libdir=usr/lib/x86_64-linux-gnu
manifest_name=VkLayer_khronos_validation.json

fetch_complete "$bookworm_debs" || { echo "nvidia-run: $bookworm_debs is missing or incomplete (scripts/nvidia-bundle.sh)" >&2; exit 1; }
fetch_require dpkg flock

# 1. The loader, GL dispatch libraries, the 1.3.239 layer and registry: into the prefix, once.
stamp="$root/var/lib/rtconf-bundle.stamp"
want=$(cd "$bookworm_debs" && ls -1 ./*.deb | sort | tr '\n' ' ')
if [[ "$(cat "$stamp" 2>/dev/null)" != "$want" ]]; then
    mkdir -p "$root/var/lib"
    exec {unpack_lock}>"$root/var/lib/rtconf-bundle.lock"
    flock "$unpack_lock"
    if [[ "$(cat "$stamp" 2>/dev/null)" != "$want" ]]; then
        for deb in "$bookworm_debs"/*.deb; do
            dpkg -x "$deb" "$prefix"
        done
        [[ "$prefix" == / ]] && ldconfig
        printf '%s' "$want" >"$stamp.new" && mv -f "$stamp.new" "$stamp"
        echo "nvidia-run: unpacked $(echo "$want" | wc -w) bookworm packages into $prefix" >&2
    fi
    exec {unpack_lock}>&-
fi
export PATH="$root/usr/bin:$PATH"
[[ "$prefix" == / ]] || export LD_LIBRARY_PATH="$root/$libdir${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"

# 2. The layer.
if [[ "$layer" == 1.4.309 ]]; then
    # trixie's layer and libstdc++ need glibc 2.38 (Ubuntu 24.04 has 2.39, bookworm 2.36).
    glibc=$(getconf GNU_LIBC_VERSION 2>/dev/null | awk '{ print $2 }')
    if [[ -n "$glibc" ]] && ! printf '2.38\n%s\n' "$glibc" | sort -V -C; then
        echo "nvidia-run: the 1.4.309 layer needs glibc >= 2.38; this machine has $glibc (here: scripts/trixie-chroot.sh)" >&2
        exit 1
    fi
    fetch_complete "$trixie_debs" || { echo "nvidia-run: $trixie_debs is missing or incomplete (scripts/nvidia-bundle.sh)" >&2; exit 1; }
    layer_dir="$repo_root/target/layers/1.4.309-carried"
    if ! fetch_complete "$layer_dir" || [[ "$trixie_debs/.rtconf-complete" -nt "$layer_dir/.rtconf-complete" ]]; then
        fetch_lock "$layer_dir"
        if ! fetch_complete "$layer_dir" || [[ "$trixie_debs/.rtconf-complete" -nt "$layer_dir/.rtconf-complete" ]]; then
            fetch_stage "$layer_dir"
            for deb in "$trixie_debs"/*.deb; do
                dpkg -x "$deb" "$FETCH_STAGE"
            done
            fetch_commit "$FETCH_STAGE" "$layer_dir"
        fi
    fi
    export VK_LAYER_PATH="$layer_dir/usr/share/vulkan/explicit_layer.d"
    export LD_LIBRARY_PATH="$layer_dir/$libdir${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
    registry="$layer_dir/usr/share/vulkan/registry"
else
    export VK_LAYER_PATH="$root/usr/share/vulkan/explicit_layer.d"
    registry="$root/usr/share/vulkan/registry"
fi
manifest="$VK_LAYER_PATH/$manifest_name"
[[ -s "$manifest" ]] || { echo "nvidia-run: no layer manifest at $manifest" >&2; exit 1; }
got=$(grep -o '"api_version": *"[^"]*"' "$manifest" | grep -o '[0-9][0-9.]*' || true)
[[ "$got" == "$layer" ]] || { echo "nvidia-run: $manifest is layer $got, not $layer" >&2; exit 1; }

# 3. The driver and the binary.
export VK_DRIVER_FILES=${VK_DRIVER_FILES:-/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json}
[[ -f "$VK_DRIVER_FILES" ]] || echo "nvidia-run: warning: no ICD manifest at $VK_DRIVER_FILES" >&2
export RTCONF_HOME="$repo_root"
bin=${RTCONF_BIN:-}
if [[ -z "$bin" ]]; then
    bin="$repo_root/.gl/bin/rtconf"
    [[ -x "$bin" ]] || bin="$repo_root/target/release/rtconf"
fi
[[ -x "$bin" ]] || { echo "nvidia-run: no rtconf binary ($bin)" >&2; exit 1; }

args=("$@")
if [[ " run stress replay detect " == *" ${args[0]} "* ]] && ! printf '%s\n' "${args[@]}" | grep -q -- '^--from'; then
    args=("${args[0]}" --from "$registry" "${args[@]:1}")
fi
echo "nvidia-run: layer $got ($VK_LAYER_PATH), ICD $VK_DRIVER_FILES, registry $registry" >&2
echo "nvidia-run: $bin ${args[*]}" >&2
exec "$bin" "${args[@]}"
