# Sourced by the project's scripts: every download and unpack goes through here, so that a
# directory they produce appears all at once (built in a staging directory beside it, on the same
# filesystem, then renamed into place) and two runs for the same directory are serialised under a
# lock (flock). A reader therefore sees a directory either absent or complete, never a half-written
# file. Debian packages come through a private apt configuration (its own sources list, lists and
# cache in a temporary directory): the machine's sources are never touched.
#
# A script that sources this file leaves the EXIT trap to it and adds what it wants removed at exit to
# fetch_cleanup_paths.
# Functions (all print their errors on stderr and return non-zero):
#   fetch_lock DIR             take the exclusive lock of DIR (DIR.lock beside it) until the shell exits
#   fetch_complete DIR         true when DIR was completed by fetch_commit
#   fetch_stage DIR            make a new empty staging directory beside DIR, named in $FETCH_STAGE
#                              (removed on exit unless fetch_commit renamed it)
#   fetch_commit STAGE DIR     mark STAGE complete and rename it to DIR (replacing an older DIR)
#   fetch_apt_init SUITE...    a private apt configuration for SUITEs of the Debian mirror (amd64)
#   fetch_debs OUTDIR PKG...   apt-get download PKGs (names or name=version) into OUTDIR
#   fetch_deb_version DEB      the Version field of a .deb file
#   fetch_require TOOL...      fail (status 2) unless every TOOL is on PATH
# Environment: DEBIAN_MIRROR (default http://deb.debian.org/debian), TMPDIR.

fetch_marker=.rtconf-complete
fetch_cleanup_paths=()

fetch_cleanup() {
    local p
    for p in "${fetch_cleanup_paths[@]}"; do
        [[ -n "$p" ]] && rm -rf -- "$p"
    done
    return 0
}
trap fetch_cleanup EXIT

fetch_lock() {
    local dir=${1%/}
    mkdir -p "$(dirname "$dir")"
    local fd
    exec {fd}>"$dir.lock"
    if ! flock -w "${FETCH_LOCK_TIMEOUT:-1800}" "$fd"; then
        echo "fetch: timed out waiting for the lock $dir.lock" >&2
        return 1
    fi
}

fetch_complete() {
    [[ -f "${1%/}/$fetch_marker" ]]
}

FETCH_STAGE=

fetch_stage() {
    local dir=${1%/}
    mkdir -p "$(dirname "$dir")"
    FETCH_STAGE=$(mktemp -d "$(dirname "$dir")/.$(basename "$dir").stage.XXXXXX") || return 1
    fetch_cleanup_paths+=("$FETCH_STAGE")
    chmod 755 "$FETCH_STAGE"
}

fetch_commit() {
    local stage=${1%/} dir=${2%/} stale=
    date -u +%Y-%m-%dT%H:%M:%SZ >"$stage/$fetch_marker"
    if [[ -e "$dir" || -L "$dir" ]]; then
        # An older directory (left incomplete by an interrupted run, or made for another set of
        # packages): move it aside first, so the rename below has a free name (rename(2) replaces
        # only an empty directory); it is removed at exit.
        stale=$(mktemp -u "$(dirname "$dir")/.$(basename "$dir").stale.XXXXXX")
        mv -T -- "$dir" "$stale"
        fetch_cleanup_paths+=("$stale")
    fi
    mv -T -- "$stage" "$dir"
    # The new directory is in place: the old one goes now, not at exit, so what follows (a size
    # check of the folder around it) sees only the new one.
    [[ -z "$stale" ]] || rm -rf -- "$stale"
}

fetch_apt_dir=
fetch_apt_opts=()

fetch_apt_init() {
    local mirror=${DEBIAN_MIRROR:-http://deb.debian.org/debian}
    local keyring=/usr/share/keyrings/debian-archive-keyring.gpg
    fetch_apt_dir=$(mktemp -d "${TMPDIR:-/tmp}/rtconf-apt.XXXXXX") || return 1
    fetch_cleanup_paths+=("$fetch_apt_dir")
    mkdir -p "$fetch_apt_dir/lists/partial" "$fetch_apt_dir/archives/partial" "$fetch_apt_dir/cache"
    : >"$fetch_apt_dir/status"
    local suite signed=
    [[ -r "$keyring" ]] && signed="[signed-by=$keyring] "
    for suite in "$@"; do
        echo "deb ${signed}${mirror%/} $suite main" >>"$fetch_apt_dir/sources.list"
    done
    fetch_apt_opts=(
        -o "Dir::Etc::SourceList=$fetch_apt_dir/sources.list"
        -o "Dir::Etc::SourceParts=/dev/null"
        -o "Dir::Etc::Preferences=/dev/null"
        -o "Dir::Etc::PreferencesParts=/dev/null"
        -o "Dir::State::Lists=$fetch_apt_dir/lists"
        -o "Dir::Cache::Archives=$fetch_apt_dir/archives"
        -o "Dir::Cache=$fetch_apt_dir/cache"
        -o "Dir::State::status=$fetch_apt_dir/status"
        -o "APT::Architecture=amd64"
        -o "APT::Architectures=amd64"
        -o "APT::Sandbox::User=root"
        -o "Debug::NoLocking=1"
        -o "Acquire::Languages=none"
        -q
    )
    if ! apt-get "${fetch_apt_opts[@]}" update >"$fetch_apt_dir/update.log" 2>&1; then
        cat "$fetch_apt_dir/update.log" >&2
        echo "fetch: apt-get update failed for: $*" >&2
        return 1
    fi
}

fetch_debs() {
    local out=$1
    shift
    mkdir -p "$out"
    if ! (cd "$out" && apt-get "${fetch_apt_opts[@]}" download "$@") >"$fetch_apt_dir/download.log" 2>&1; then
        cat "$fetch_apt_dir/download.log" >&2
        echo "fetch: apt-get download failed for: $*" >&2
        return 1
    fi
}

fetch_deb_version() {
    dpkg-deb -f "$1" Version
}

fetch_require() {
    local tool
    for tool in "$@"; do
        command -v "$tool" >/dev/null 2>&1 || { echo "fetch: $tool not found" >&2; return 2; }
    done
}
