#!/usr/bin/env bash
# Runs one libFuzzer target of rtconf-fuzz for SECONDS (default 600), in fork mode so that it goes on
# past crashes; new inputs go to fuzz/work/corpus/TARGET, crashes to fuzz/work/artifacts/TARGET/, the log
# to fuzz/work/TARGET.log. Needs the nightly toolchain and cargo-fuzz (fuzz/README.md).
set -euo pipefail
target=${1:?usage: fuzz/run.sh TARGET [SECONDS]}
seconds=${2:-600}
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
extra=()
case $target in
  trace_case) extra=(cases/hand cases/edge cases/resources) dict=yaml ;;
  build_case) extra=(cases/build) dict=yaml ;;
  triage) extra=(triage) dict=yaml ;;
  vk_xml) dict=xml ;;
  validusage_json | device_profile) dict=json ;;
  manpage_*) dict=manpage ;;
  baseline | case_patterns) dict=lines ;;
  *) echo "unknown target $target" >&2; exit 2 ;;
esac
work=fuzz/work
mkdir -p "$work/corpus/$target" "$work/artifacts/$target"
cargo +nightly fuzz run -s none --fuzz-dir fuzz/libfuzzer "$target" \
  "$work/corpus/$target" "fuzz/corpus/$target" "${extra[@]}" -- \
  -fork=1 -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1 \
  -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 \
  -dict="fuzz/dict/$dict.dict" -artifact_prefix="$work/artifacts/$target/" 2>&1 | tee "$work/$target.log" | grep -E '^#[0-9]+:' | tail -1
