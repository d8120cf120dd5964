#!/usr/bin/env bash
# Gather what the NVIDIA machine lacks (it has the driver, no Vulkan loader, no validation layer,
# no network) into folders that git ignores, for scripts/nvidia-run.sh to use there:
#   .gl/debs/          bookworm's amd64 .debs: libvulkan1, libglvnd0, libegl1, libgl1, libglx0,
#                      libopengl0, libgles2, vulkan-validationlayers (1.3.239) and libvulkan-dev
#                      (the 1.3.239 registry at rtconf's default /usr/share/vulkan/registry)
#   .gl/bin/rtconf     a stripped copy of target/release/rtconf, when that exists (--no-binary: none)
#   .gl-1.4.309/debs/  trixie's vulkan-validationlayers (1.4.309), libstdc++6, libgcc-s1 and
#                      libvulkan-dev (the 1.4.309 registry) through scripts/layer-1.4.309.sh
# Each folder appears whole (staged beside it, then renamed) under a lock; a complete one is kept
# (remove it to fetch it again). Prints the size of each folder and the total (kept under 40 MiB).
#
# usage: scripts/nvidia-bundle.sh [--no-binary]
# Then carry `.gl` and `.gl-1.4.309` to the device machine and run scripts/nvidia-run.sh there.
set -euo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=lib/fetch.sh
source "$repo_root/scripts/lib/fetch.sh"

with_binary=1
while [[ $# -gt 0 ]]; do
    case "$1" in
        --no-binary) with_binary=0; shift ;;
        -h|--help) sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "nvidia-bundle: unknown argument $1" >&2; exit 2 ;;
    esac
done

bookworm_debs="$repo_root/.gl/debs"
trixie_debs="$repo_root/.gl-1.4.309/debs"
bin_dir="$repo_root/.gl/bin"
packages=(libvulkan1 libglvnd0 libegl1 libgl1 libglx0 libopengl0 libgles2 vulkan-validationlayers libvulkan-dev)
limit_mib=40

fetch_require apt-get dpkg-deb flock

bookworm_ready() {
    fetch_complete "$bookworm_debs" && [[ "$(cat "$bookworm_debs/.rtconf-packages" 2>/dev/null)" == "${packages[*]}" ]]
}
if ! bookworm_ready; then
    fetch_lock "$bookworm_debs"
    if ! bookworm_ready; then
        echo "nvidia-bundle: updating private package lists (bookworm)" >&2
        fetch_apt_init bookworm
        fetch_stage "$bookworm_debs"
        echo "nvidia-bundle: downloading ${packages[*]} (bookworm, amd64)" >&2
        fetch_debs "$FETCH_STAGE" "${packages[@]}"
        layer=$(ls "$FETCH_STAGE"/vulkan-validationlayers_*.deb)
        [[ "$(fetch_deb_version "$layer")" == 1.3.239.* ]] || {
            echo "nvidia-bundle: bookworm's layer is $(fetch_deb_version "$layer"), not 1.3.239" >&2
            exit 1
        }
        printf '%s\n' "${packages[*]}" >"$FETCH_STAGE/.rtconf-packages"
        fetch_commit "$FETCH_STAGE" "$bookworm_debs"
    fi
fi

# layer-1.4.309.sh takes the lock of this folder itself.
bash "$repo_root/scripts/layer-1.4.309.sh" --with-registry --debs "$trixie_debs" >/dev/null

if [[ $with_binary -eq 1 ]]; then
    bin="$repo_root/target/release/rtconf"
    if [[ -x "$bin" ]]; then
        fetch_lock "$bin_dir"
        if ! fetch_complete "$bin_dir" || [[ "$bin" -nt "$bin_dir/rtconf" ]]; then
            fetch_stage "$bin_dir"
            strip -o "$FETCH_STAGE/rtconf" "$bin"
            fetch_commit "$FETCH_STAGE" "$bin_dir"
        fi
    else
        echo "nvidia-bundle: no target/release/rtconf (cargo build --release -p rtconf-harness --bin rtconf); bundle without it" >&2
    fi
fi

size_of() { du -sbL "$@" 2>/dev/null | awk '{ s += $1 } END { print s + 0 }'; }
parts=("$bookworm_debs" "$trixie_debs")
[[ -d "$bin_dir" ]] && parts+=("$bin_dir")
for p in "${parts[@]}"; do
    printf 'nvidia-bundle: %-32s %6.1f MiB\n' "${p#"$repo_root"/}" "$(size_of "$p" | awk '{ print $1 / 1048576 }')"
done
total=$(size_of "$repo_root/.gl" "$repo_root/.gl-1.4.309")
printf 'nvidia-bundle: total (.gl + .gl-1.4.309)        %6.1f MiB\n' "$(awk -v t="$total" 'BEGIN { print t / 1048576 }')"
if (( total > limit_mib * 1048576 )); then
    echo "nvidia-bundle: the bundle exceeds $limit_mib MiB" >&2
    exit 1
fi
