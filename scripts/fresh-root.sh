#!/usr/bin/env bash
# A developer's check of the README's quick start on a clean Debian 12: debootstraps a minimal
# bookworm root (cached, pristine; each run works on a fresh copy), copies this machine's Rust
# toolchain into it (rustup's default toolchain and ~/.cargo/bin; no crates), clones the repository's
# committed HEAD into /work/main with /work/shared beside it (the seeds the tests read), and runs
# there, each under `time`:
#     bash scripts/conformance.sh --count 1
#     bash scripts/test.sh
# Both install what is missing themselves (apt inside the root; the network must reach Debian's
# mirrors and crates.io). Not called by CI. Needs root.
#
# usage: scripts/fresh-root.sh [--keep] [--out DIR] [--base DIR]
#   --out DIR   logs and timings (default target/fresh-root/<UTC time>)
#   --base DIR  the cached pristine root (default /var/tmp/rtconf-bookworm-base)
#   --keep      keep the work root after the run (its path is printed)
# Exit status: 0 when both commands succeed, else 1 (the logs say which failed).
set -euo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=lib/fetch.sh
source "$repo_root/scripts/lib/fetch.sh"

base=/var/tmp/rtconf-bookworm-base
out=
keep=0
while [[ $# -gt 0 ]]; do
    case "$1" in
        --keep) keep=1; shift ;;
        --out) out=$2; shift 2 ;;
        --base) base=$2; shift 2 ;;
        -h|--help) sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "fresh-root: unknown argument $1" >&2; exit 2 ;;
    esac
done
[[ "$(id -u)" -eq 0 ]] || { echo "fresh-root: needs root (debootstrap, chroot, mount)" >&2; exit 2; }
base=$(realpath -m "$base")
out=$(realpath -m "${out:-$repo_root/target/fresh-root/$(date -u +%Y%m%dT%H%M%SZ)}")
mkdir -p "$out"
rustup_home=${RUSTUP_HOME:-$HOME/.rustup}
cargo_home=${CARGO_HOME:-$HOME/.cargo}
commit=$(git -C "$repo_root" rev-parse HEAD)
shared=$(cd "$repo_root/.." && pwd)/shared
[[ -d "$shared" ]] || shared=/work/shared

# 1. The pristine base: minbase bookworm, nothing else.
if ! fetch_complete "$base"; then
    fetch_lock "$base"
    if ! fetch_complete "$base"; then
        command -v debootstrap >/dev/null 2>&1 ||
            DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -o DPkg::Lock::Timeout=600 debootstrap >&2
        fetch_stage "$base"
        echo "fresh-root: debootstrap bookworm (minbase) into $FETCH_STAGE" >&2
        if ! debootstrap --variant=minbase bookworm "$FETCH_STAGE" "${DEBIAN_MIRROR:-http://deb.debian.org/debian}" \
                >"$out/debootstrap.log" 2>&1; then
            tail -n 30 "$out/debootstrap.log" >&2
            exit 1
        fi
        # No service starts inside the root when packages are installed.
        printf '#!/bin/sh\nexit 101\n' >"$FETCH_STAGE/usr/sbin/policy-rc.d"
        chmod 755 "$FETCH_STAGE/usr/sbin/policy-rc.d"
        rm -rf "$FETCH_STAGE"/var/cache/apt/archives/*.deb
        fetch_commit "$FETCH_STAGE" "$base"
    fi
fi

# 2. A fresh copy of it, with the toolchain, the clone and the shared data.
work=$(mktemp -d /var/tmp/rtconf-fresh-root.XXXXXX)
cleanup_work() {
    if grep -qF " $work/" /proc/self/mountinfo; then
        echo "fresh-root: mounts remain under $work; not removing it" >&2
    elif [[ $keep -eq 0 ]]; then
        rm -rf "$work"
    else
        echo "fresh-root: kept $work" >&2
    fi
}
trap 'cleanup_work; fetch_cleanup' EXIT
echo "fresh-root: copying the base into $work" >&2
cp -a "$base/." "$work/"
rm -f "$work/.rtconf-complete"

default_toolchain=$(sed -n 's/^default_toolchain *= *"\(.*\)"/\1/p' "$rustup_home/settings.toml")
[[ -n "$default_toolchain" && -d "$rustup_home/toolchains/$default_toolchain" ]] ||
    { echo "fresh-root: no default rustup toolchain in $rustup_home" >&2; exit 1; }
echo "fresh-root: copying rustup's $default_toolchain and $cargo_home/bin" >&2
mkdir -p "$work/root/.rustup/toolchains" "$work/root/.cargo"
cp -a "$rustup_home/settings.toml" "$work/root/.rustup/"
[[ -d "$rustup_home/update-hashes" ]] && cp -a "$rustup_home/update-hashes" "$work/root/.rustup/"
cp -a "$rustup_home/toolchains/$default_toolchain" "$work/root/.rustup/toolchains/"
# Other names of the same toolchain (a pinned version linking to it).
for link in "$rustup_home"/toolchains/*; do
    if [[ -L "$link" && "$(readlink -f "$link")" == "$(readlink -f "$rustup_home/toolchains/$default_toolchain")" ]]; then
        ln -s "/root/.rustup/toolchains/$default_toolchain" "$work/root/.rustup/toolchains/$(basename "$link")"
    fi
done
cp -a "$cargo_home/bin" "$work/root/.cargo/"
[[ -f "$cargo_home/env" ]] && cp -a "$cargo_home/env" "$work/root/.cargo/"

echo "fresh-root: cloning $commit" >&2
mkdir -p "$work/work"
git clone -q --no-checkout "$repo_root" "$work/work/main"
git -C "$work/work/main" checkout -q "$commit"
if [[ -d "$shared" ]]; then
    cp -r "$shared" "$work/work/shared"
fi
# The machine's network set-up: its resolver, and the certificate authorities it added locally (an
# egress proxy's); ca-certificates inside the root picks these up when it is installed.
cp -L /etc/resolv.conf "$work/etc/resolv.conf"
if compgen -G "/usr/local/share/ca-certificates/*.crt" >/dev/null; then
    mkdir -p "$work/usr/local/share/ca-certificates"
    cp /usr/local/share/ca-certificates/*.crt "$work/usr/local/share/ca-certificates/"
fi

# 3. The two commands, timed, inside the root.
run_in_root() {
    local name=$1
    shift
    local script
    script=$(printf 'cd /work/main && export CI=true && { time %s ; } >%q 2>&1 </dev/null; echo $? >%q' \
        "$*" "/work/$name.log" "/work/$name.status")
    unshare --mount --propagation private -- bash -c "
        set -e
        mount -t proc proc '$work/proc'
        mount --rbind /dev '$work/dev'
        mount --rbind /sys '$work/sys'
        exec chroot '$work' env -i HOME=/root LANG=C.UTF-8 TERM=dumb \
            PATH=/root/.cargo/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
            bash -c $(printf %q "$script")
    "
    cp "$work/work/$name.log" "$out/$name.log"
    local status
    status=$(cat "$work/work/$name.status")
    local took
    took=$(grep -E '^real' "$out/$name.log" | tail -n1 | awk '{ print $2 }')
    printf '%-12s exit %s, real %s  (%s)\n' "$name" "$status" "$took" "$*" | tee -a "$out/summary.txt"
    [[ "$status" -eq 0 ]]
}

{
    echo "fresh-root: commit $commit"
    echo "toolchain: $default_toolchain"
} | tee "$out/summary.txt"
ok=0
run_in_root conformance bash scripts/conformance.sh --count 1 || ok=1
tail -n 3 "$out/conformance.log" | sed 's/^/    /'
run_in_root test bash scripts/test.sh || ok=1
grep -E '^tests: ' "$out/test.log" | tail -n1 | tee -a "$out/summary.txt" | sed 's/^/    /'
echo "fresh-root: logs in $out" >&2
exit "$ok"
