#!/usr/bin/env bash
# Compares two builds of a rate benchmark on one workload by running them in turn, round after
# round, so a change in the machine's load moves both alike; prints each build's rates and their
# medians, and the median of each round's B/A. A change of a few percent needs many rounds on a
# shared machine: one run's spread is often wider than that.
#
#   bash scripts/bench-ab.sh BENCH BIN_A BIN_B [ROUNDS] [WORKLOAD]
#
# BENCH is `render_rays` (oracle rays/s, the oracle/lavapipe ratio and, where the build prints it,
# the ratio with the judgement of the records included; lavapipe through
# VK_DRIVER_FILES, set to Mesa's lvp_icd.json when unset) or `expected_launch` (the oracle's
# launch rays/s alone). BIN_A and BIN_B are the bench executables of the two builds, e.g. copies of
# the path `cargo bench -p rtconf-harness --bench render_rays --no-run` prints, taken before and
# after a change. ROUNDS defaults to 8, WORKLOAD (a substring of the workload's name) to
# `instanced`; RTCONF_BENCH_PASSES is passed through (each bench's own default when unset).
set -euo pipefail

if [[ $# -lt 3 ]]; then
    sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
fi
bench=$1 bin_a=$2 bin_b=$3 rounds=${4:-8} workload=${5:-instanced}
case $bench in
render_rays | expected_launch) ;;
*)
    echo "bench-ab.sh: unknown bench '$bench' (render_rays or expected_launch)" >&2
    exit 2
    ;;
esac
for bin in "$bin_a" "$bin_b"; do
    [[ -x $bin ]] || { echo "bench-ab.sh: $bin: not an executable" >&2; exit 2; }
done
[[ $rounds =~ ^[1-9][0-9]*$ ]] || { echo "bench-ab.sh: rounds '$rounds': not a positive count" >&2; exit 2; }
export VK_DRIVER_FILES=${VK_DRIVER_FILES:-/usr/share/vulkan/icd.d/lvp_icd.json}
export RTCONF_BENCH_ONLY=$workload

# One run of a build: "rate [ratio paired]" of the workload's row (the columns after the name).
run_once() {
    local out
    out=$("$1" 2>/dev/null) || { echo "bench-ab.sh: $1 failed" >&2; return 1; }
    awk -v bench="$bench" '
        # A build whose render_rays prints the judged ratio has one column more before "exact %".
        /^workload/ { header = 1; judged = index($0, "judged ratio") > 0; next }
        header && NF >= 8 {
            # The name has spaces; the numbers are counted from the end of the row.
            if (bench == "render_rays" && $NF != "pass") { print "lavapipe not judged pass: " $0 > "/dev/stderr"; exit 1 }
            if (bench == "render_rays") print $(NF-6-judged), $(NF-4-judged), $(NF-3-judged), (judged ? $(NF-2) : "-")
            else print $(NF-10)
            found = 1
            exit
        }
        END { if (!found) exit 1 }' <<<"$out" || { echo "bench-ab.sh: no '$workload' row from $1" >&2; return 1; }
}

results=$(mktemp)
trap 'rm -f "$results"' EXIT
# The two builds take turns going first (A B, then B A), so neither always runs on a machine the
# other has just warmed. One build against a copy of itself, 24 rounds: within about 1 %.
for ((r = 1; r <= rounds; r++)); do
    order="A B"
    ((r % 2 == 0)) && order="B A"
    for side in $order; do
        bin=$bin_a
        [[ $side == B ]] && bin=$bin_b
        echo "$side $r $(run_once "$bin")" >>"$results"
    done
done
awk -v bench="$bench" '
    function median(list,    n, a, i, j, t) {
        n = split(list, a, " ")
        for (i = 2; i <= n; i++) for (j = i; j > 1 && a[j-1] + 0 > a[j] + 0; j--) { t = a[j]; a[j] = a[j-1]; a[j-1] = t }
        return n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2
    }
    { rate[$1] = rate[$1] " " $3; ratio[$1] = ratio[$1] " " $4; paired[$1] = paired[$1] " " $5; judged[$1] = judged[$1] " " $6; of[$1, $2] = $3 }
    END {
        for (s = 0; s < 2; s++) {
            k = s ? "B" : "A"
            printf "%s rates:%s\n", k, rate[k]
            if (bench == "render_rays") {
                printf "%s median rate %.0f, ratio %.3f, paired %.3f", k, median(rate[k]), median(ratio[k]), median(paired[k])
                if (judged[k] !~ /-/) printf ", judged ratio %.3f", median(judged[k])
                printf "\n"
            }
            else printf "%s median rate %.0f\n", k, median(rate[k])
        }
        printf "B/A median rate: %.4f\n", median(rate["B"]) / median(rate["A"])
        # In each round B over A (the two run back to back), then the median of those: steadier
        # where the speed of the machine drifts over the rounds.
        for (r = 1; (("A", r) in of) && (("B", r) in of); r++) rounds = rounds " " of["B", r] / of["A", r]
        printf "B/A median of the ratios in each round: %.4f\n", median(rounds)
    }' "$results"
