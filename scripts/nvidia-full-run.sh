#!/usr/bin/env bash
# The whole NVIDIA run, repeatable from a clean checkout by anyone with such a machine.
#
# Two halves, because the NVIDIA machine has no network, no Vulkan loader, layer or compiler:
#
#   here (Debian 12 with Rust, apt and network; the checkout's root):
#     bash scripts/nvidia-full-run.sh --prepare
#       builds target/release/rtconf and gathers the bundle (.gl/ and .gl-1.4.309/, scripts/nvidia-bundle.sh);
#       copy the checkout with those two folders to the NVIDIA machine.
#
#   there (the NVIDIA machine, as root, in the copied checkout):
#     bash scripts/nvidia-full-run.sh --out DIR [--count N] [--valid-count N] [--seed S] [--commit SHA]
#                                     [--phases LIST] [--phase-timeout S] [--stress-timeout S]
#                                     [--tar FILE]
#       probe   rtconf probe of the live device into profiles/nvidia-h200.json (every run below uses it)
#       trace   the trace commands the profile supports, valid and invalid cases, layer 1.3.239
#       build   vkCmdBuildAccelerationStructuresIndirectKHR, layer 1.3.239
#       render  valid cases only, --valid-count per command (rendered scenes judged by the tracer), 1.3.239
#       trace-1.4.309, build-1.4.309   the same under trixie's 1.4.309 layer and its own registry
#       lavapipe-findings  lavapipe's build findings (cases/build/lavapipe-*.yaml and the first-vertex evidence) on
#               NVIDIA, then as the exported C programs --prepare compiled (.gl/bin/repro-build/; the pipeline check)
#       findings  the driver findings kept under cases/nvidia-h200/device-lost/ (and their reduced variants), twice each,
#               then the same cases as the exported C programs --prepare compiled (.gl/bin/repro/)
#       detect  rtconf detect: seeded faults by kind and size (the suite's detection against run time)
#       stress  rtconf stress: the numerical stress families at full size on NVIDIA, layer 1.3.239, under
#               --stress-timeout (default 3600 s: the model judges every ray on the CPU); DIR/stress/
#               holds stress.json and stress.png, and the README gets the per-family table
#     Default: every phase, in that order. Each phase writes DIR/PHASE/ (the run folder) and DIR/PHASE.log;
#     a phase that fails or runs past --phase-timeout is recorded with its exit status and the next one
#     runs. DIR/README.md gets one row per phase: the command, the exit status, the counts from
#     summary.json (stress: its cases by outcome from stress.json). --tar packs DIR into one file (for machines that hand back few files).
#
# The run phases take baselines/nvidia-h200.csv (known findings by case name, empty today) and, as every
# run on driver nvidia, triage/nvidia.yaml (the DEVICE_LOST finding, triaged by the shape the model gives a case).
# The commit is the one --prepare built the bundle from (.gl/COMMIT), else the checkout's, unless
# --commit names it.
set -uo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"

out="" count=4 valid_count=100 seed="" commit="" tar_file="" phase_timeout=300 stress_timeout=3600
phases="probe trace build render trace-1.4.309 build-1.4.309 lavapipe-findings findings stress detect"
prepare=0
while [[ $# -gt 0 ]]; do
    case "$1" in
        --prepare) prepare=1; shift ;;
        --out) out=$2; shift 2 ;;
        --count) count=$2; shift 2 ;;
        --valid-count) valid_count=$2; shift 2 ;;
        --seed) seed=$2; shift 2 ;;
        --commit) commit=$2; shift 2 ;;
        --phases) phases=$2; shift 2 ;;
        --phase-timeout) phase_timeout=$2; shift 2 ;;
        --stress-timeout) stress_timeout=$2; shift 2 ;;
        --tar) tar_file=$2; shift 2 ;;
        -h|--help) sed -n '2,35p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "nvidia-full-run: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
done

# lavapipe's build findings (triage/lavapipe.yaml's evidence): on NVIDIA, does the device build them as
# the model does?
lavapipe_build_findings="cases/build/lavapipe-*.yaml cases/build/indexed-first-vertex-shifted-primitives.yaml"

if [[ $prepare -eq 1 ]]; then
    set -e
    cargo build --release -p rtconf-cli --bin rtconf
    bash scripts/nvidia-bundle.sh
    # The commit the bundle was built from (a copied checkout's .git may be older than its files).
    git rev-parse --short HEAD >.gl/COMMIT 2>/dev/null || true
    # The driver findings as standalone C programs (the machine there has no compiler): one per case
    # of cases/nvidia-h200/device-lost/ that `rtconf export` writes, linked against the loader the bundle carries.
    mkdir -p .gl/bin/repro
    for c in cases/nvidia-h200/device-lost/*.yaml; do
        n=$(basename "$c" .yaml)
        if target/release/rtconf export "$c" --out "target/repro/$n" >/dev/null 2>&1 \
            && cc -O1 "target/repro/$n/repro.c" -lvulkan -o ".gl/bin/repro/$n"; then
            echo "nvidia-full-run: .gl/bin/repro/$n"
        else
            echo "nvidia-full-run: $n: not exported ($(target/release/rtconf export "$c" --out "target/repro/$n" 2>&1 | tail -1))"
        fi
    done
    # lavapipe's build findings as C too: on NVIDIA (no ray query) their traced check takes the pipeline.
    mkdir -p .gl/bin/repro-build
    for c in $lavapipe_build_findings; do
        n=$(basename "$c" .yaml)
        if target/release/rtconf export "$c" --out "target/repro-build/$n" >/dev/null 2>&1 \
            && cc -O1 "target/repro-build/$n/repro.c" -lvulkan -o ".gl/bin/repro-build/$n"; then
            echo "nvidia-full-run: .gl/bin/repro-build/$n"
        else
            echo "nvidia-full-run: $n: not exported ($(target/release/rtconf export "$c" --out "target/repro-build/$n" 2>&1 | tail -1))"
        fi
    done
    echo "nvidia-full-run: ready; carry .gl and .gl-1.4.309 with the checkout, then run with --out there"
    exit 0
fi

[[ -n "$out" ]] || { echo "nvidia-full-run: --out DIR (or --prepare; see --help)" >&2; exit 2; }
[[ -n "$commit" ]] || commit=$(cat .gl/COMMIT 2>/dev/null || git rev-parse HEAD 2>/dev/null || echo unknown)
mkdir -p "$out"
out=$(realpath "$out")
readme="$out/README.md"
profile=nvidia-h200
bin="$repo_root/.gl/bin/rtconf"
[[ -x "$bin" ]] || bin="$repo_root/target/release/rtconf"

{
    echo "# NVIDIA run of rtconf"
    echo
    echo "- commit: \`$commit\`"
    echo "- started: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
    echo "- host: $(uname -srm); $(getconf GNU_LIBC_VERSION 2>/dev/null)"
    if command -v nvidia-smi >/dev/null; then
        echo "- GPU: $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null | head -1)"
    fi
    echo "- script: \`bash scripts/nvidia-full-run.sh --out DIR --count $count --valid-count $valid_count${seed:+ --seed $seed} --phases '$phases'\`"
    echo
    echo "| phase | command | exit | seconds | cases | pass | triaged | unsupported | not-realised | fail | crash | timeout | case-error | stale triage |"
    echo "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
} >"$readme"

# One row of the README from a run folder's summary.json (python3 where there is one).
row() {
    local phase=$1 cmd=$2 rc=$3 secs=$4 summary="$out/$1/summary.json"
    local counts="| | | | | | | | | |"
    if [[ -s "$out/$1/stress.json" ]] && command -v python3 >/dev/null; then
        # A stress run: its trace cases by outcome (pass, triaged, unsupported, not-realised, fail,
        # crash, timeout, case-error summed over the families).
        counts=$(python3 - "$out/$1/stress.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
total = {}
for f in s["families"]:
    for k, n in f["outcomes"].items():
        total[k] = total.get(k, 0) + n
cases = sum(f["cases"] for f in s["families"])
keys = ["pass", "triaged", "unsupported", "not-realised", "fail", "crash", "timeout", "case-error"]
print("| " + " | ".join([str(cases)] + [str(total.get(k, 0)) for k in keys]) + " | |")
PY
)
    elif [[ -s "$summary" ]] && command -v python3 >/dev/null; then
        counts=$(python3 - "$summary" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
keys = ["cases", "passed", "triaged", "unsupported", "not_realised", "failed", "crashes", "timeouts", "case_errors"]
t = s.get("triage") or {}
stale = len(t.get("stale") or []) if t.get("stale_judged") else "partial run"
print("| " + " | ".join(str(s.get(k, "")) for k in keys) + f" | {stale} |")
PY
)
    fi
    echo "| $phase | \`$cmd\` | $rc | $secs $counts" >>"$readme"
}

# Runs one phase through scripts/nvidia-run.sh under a time limit and records it.
phase() {
    local name=$1 layer=$2
    shift 2
    local started=$SECONDS limit=$phase_timeout
    [[ "$name" == stress ]] && limit=$stress_timeout
    echo "nvidia-full-run: $name: rtconf $*" >&2
    timeout --kill-after=10 "$limit" bash scripts/nvidia-run.sh --layer "$layer" -- "$@" \
        >"$out/$name.log" 2>&1
    local rc=$?
    row "$name" "rtconf $* (layer $layer)" "$rc" "$((SECONDS - started))"
    tail -5 "$out/$name.log" >&2
}

run_args=(--driver nvidia --profile "$profile" --jobs "$(nproc 2>/dev/null || echo 4)"
          --baseline baselines/nvidia-h200.csv)
# Another seed draws other cases (the baseline names the default seed's known findings).
[[ -n "$seed" ]] && run_args+=(--seed "$seed")
# The exported programs of .gl/bin/KIND/ (--prepare made them), each run once under the layer with its
# records written to DIR/KIND/; one README row each, with the lines of its log that PATTERN takes.
run_programs() {
    local kind=$1 pattern=$2 r n started rc verdict
    mkdir -p "$out/$kind"
    for r in .gl/bin/"$kind"/*; do
        [[ -x "$r" ]] || continue
        n=$(basename "$r")
        started=$SECONDS
        RTCONF_BIN="$r" timeout --kill-after=5 30 bash scripts/nvidia-run.sh -- \
            --records "$out/$kind/$n.records" >"$out/$kind/$n.log" 2>&1
        rc=$?
        verdict=$(grep -E "$pattern" "$out/$kind/$n.log" | tr '\n' ' ' | tr '|' '/')
        echo "| $kind $n | \`.gl/bin/$kind/$n\` (exported C) | $rc | $((SECONDS - started)) | $verdict | | | | | | | | | |" >>"$readme"
    done
}

for p in $phases; do
    case "$p" in
        probe)
            phase probe 1.3.239 probe --driver nvidia --out "profiles/$profile.json"
            cp -f "profiles/$profile.json" "$out/$profile.json" 2>/dev/null || true
            ;;
        trace) phase trace 1.3.239 run "${run_args[@]}" --count "$count" --out "$out/trace" ;;
        build)
            phase build 1.3.239 run "${run_args[@]}" --command vkCmdBuildAccelerationStructuresIndirectKHR \
                --count "$count" --out "$out/build"
            ;;
        render) phase render 1.3.239 run "${run_args[@]}" --valid-only --count "$valid_count" --out "$out/render" ;;
        trace-1.4.309) phase trace-1.4.309 1.4.309 run "${run_args[@]}" --count "$count" --out "$out/trace-1.4.309" ;;
        build-1.4.309)
            phase build-1.4.309 1.4.309 run "${run_args[@]}" --command vkCmdBuildAccelerationStructuresIndirectKHR \
                --count "$count" --out "$out/build-1.4.309"
            ;;
        findings)
            # The kept driver findings and their reduced variants (cases/nvidia-h200/), each run three
            # times: a finding that does not repeat shows as a flake.
            phase findings 1.3.239 run --driver nvidia --profile "$profile" --jobs 4 --retries 1 \
                --timeout 20 --cases cases/nvidia-h200/device-lost --out "$out/findings"
            # The same cases as the standalone programs a bug report carries (--prepare made them).
            run_programs repro '^(verdict|records):'
            ;;
        lavapipe-findings)
            # lavapipe's build findings run on NVIDIA (laid out for lavapipe, judged with this device's
            # profile), then as the standalone programs --prepare made of them.
            mkdir -p "$out/lavapipe-findings-cases"
            # shellcheck disable=SC2086 # the list is globs
            cp $lavapipe_build_findings "$out/lavapipe-findings-cases/"
            phase lavapipe-findings 1.3.239 run --driver nvidia --profile "$profile" --jobs 4 \
                --timeout 20 --cases "$out/lavapipe-findings-cases" --out "$out/lavapipe-findings"
            run_programs repro-build '^(check|output|verdict):'
            ;;
        stress)
            if "$bin" help stress >/dev/null 2>&1; then
                phase stress 1.3.239 stress --driver nvidia --profile "$profile" --size full \
                    --jobs "$(nproc 2>/dev/null || echo 4)" --out "$out/stress"
                stress_table=$(sed -n '/^family /,/^[0-9.]* s; /p' "$out/stress.log")
            else
                echo "| stress | (this binary has no \`rtconf stress\`) | not run | | | | | | | | | | | |" >>"$readme"
            fi
            ;;
        detect)
            # The suite's curve on the GPU: seeded faults by kind and size, detection against run time.
            phase detect 1.3.239 detect --driver nvidia --profile "$profile" --jobs "$(nproc 2>/dev/null || echo 4)" \
                --count 40 --out "$out/detect"
            ;;
        *) echo "nvidia-full-run: unknown phase $p" >&2; exit 2 ;;
    esac
done
echo >>"$readme"
if [[ -n "${stress_table:-}" ]]; then
    {
        echo "## stress (per family: rtconf stress's table; DIR/stress/stress.json and stress.png)"
        echo
        echo '```'
        echo "$stress_table"
        echo '```'
        echo
    } >>"$readme"
fi
echo "- finished: $(date -u +%Y-%m-%dT%H:%M:%SZ)" >>"$readme"

if [[ -n "$tar_file" ]]; then
    tar -C "$(dirname "$out")" -czf "$tar_file" "$(basename "$out")"
    echo "nvidia-full-run: packed $out into $tar_file ($(du -h "$tar_file" | cut -f1))" >&2
fi
cat "$readme"
