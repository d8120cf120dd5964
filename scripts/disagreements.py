#!/usr/bin/env python3
"""The disagreements of `rtconf run` results, per VUID, as a Markdown list.

Reads results.jsonl files (one CaseReport a line) of a run judged without triage, and lists every
VUID on which model and layer disagree: its direction (model-only: the model reports it, the layer
does not; layer-only: the layer reports it, the model does not), the cases it occurs in and an
example case name. Then the cases that crashed or timed out, valid cases whose output differs from
the model's or on which the layer reported a VUID outside the modelled commands, and invalid cases
whose target the model did not report. With --baseline (results of another run, e.g. the older
layer) each disagreement says whether it occurs there too; with --triage (a triage YAML) which
entry covers it.

usage: scripts/disagreements.py [--title T] [--baseline R.jsonl]... [--triage T.yaml]... R.jsonl...
"""

import argparse
import collections
import json
import re
import sys


def read_results(paths):
    rows = []
    for path in paths:
        with open(path, encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                line = line.strip()
                if not line:
                    continue
                try:
                    rows.append(json.loads(line))
                except json.JSONDecodeError as e:
                    sys.exit(f"{path}:{n}: {e}")
    return rows


def disagreements(rows):
    """(direction, vuid) -> the names of the cases where it occurs, for cases that ran."""
    found = collections.defaultdict(list)
    for r in rows:
        if r["outcome"] in ("unsupported", "crash", "timeout"):
            continue
        model, layer = set(r.get("model", [])), set(r.get("layer", []))
        for v in model - layer:
            found[("model-only", v)].append(r["case"])
        for v in layer - model:
            found[("layer-only", v)].append(r["case"])
    return found


def read_triage(paths):
    """(pattern, kind) pairs of triage files; patterns may hold `*` wildcards."""
    entries = []
    for path in paths:
        vuid = None
        with open(path, encoding="utf-8") as f:
            for line in f:
                m = re.match(r"\s*-\s+vuid:\s*(\S+)", line)
                if m:
                    vuid = m.group(1).strip("'\"")
                    continue
                m = re.match(r"\s+kind:\s*(\S+)", line)
                if m and vuid:
                    entries.append((vuid, m.group(1)))
                    vuid = None
    return entries


def covered_by(entries, vuid):
    for pattern, kind in entries:
        if re.fullmatch(".*".join(map(re.escape, pattern.split("*"))), vuid):
            return f"{kind} (`{pattern}`)" if pattern != vuid else kind
    return ""


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("results", nargs="+")
    ap.add_argument("--baseline", action="append", default=[])
    ap.add_argument("--baseline-name", default="baseline")
    ap.add_argument("--triage", action="append", default=[])
    ap.add_argument("--title", default="Disagreements between the model and the layer")
    a = ap.parse_args()

    rows = read_results(a.results)
    found = disagreements(rows)
    base = disagreements(read_results(a.baseline)) if a.baseline else None
    triage = read_triage(a.triage)

    out = [f"# {a.title}", ""]
    counts = collections.Counter(r["outcome"] for r in rows)
    out.append(
        f"{len(rows)} cases: "
        + ", ".join(f"{counts[k]} {k}" for k in ("pass", "fail", "triaged", "unsupported", "crash", "timeout"))
        + "."
    )
    model_only = sum(1 for d, _ in found if d == "model-only")
    out += [
        f"{len(found)} disagreeing VUIDs: {model_only} model-only, {len(found) - model_only} layer-only.",
        "",
    ]
    head = "| direction | VUID | cases | example case |"
    rule = "|---|---|---|---|"
    if base is not None:
        head += f" in {a.baseline_name} |"
        rule += "---|"
    if triage:
        head += " triage entry |"
        rule += "---|"
    out += [head, rule]
    for (direction, vuid), cases in sorted(found.items(), key=lambda kv: (kv[0][0], kv[0][1])):
        line = f"| {direction} | `{vuid}` | {len(cases)} | `{sorted(cases)[0]}` |"
        if base is not None:
            line += " yes |" if (direction, vuid) in base else " **no** |"
        if triage:
            line += f" {covered_by(triage, vuid)} |"
        out.append(line)
    if base is not None:
        gone = sorted(k for k in base if k not in found)
        out += ["", f"## In {a.baseline_name} only ({len(gone)})", ""]
        out += [f"- {d} `{v}` (e.g. `{sorted(base[(d, v)])[0]}`)" for d, v in gone] or ["none"]

    def section(title, picked, describe):
        out.extend(["", f"## {title} ({len(picked)})", ""])
        out.extend([f"- `{r['case']}`: {describe(r)}" for r in picked] or ["none"])

    section(
        "Crashes and timeouts",
        [r for r in rows if r["outcome"] in ("crash", "timeout")],
        lambda r: f"{r['outcome']}, target `{r.get('target')}`: {r.get('detail', '')}",
    )
    section(
        "Valid cases whose output differs from the model's",
        [r for r in rows if r.get("output_matches") is False],
        lambda r: r.get("detail", ""),
    )
    section(
        "Valid cases with layer messages outside the modelled commands",
        [r for r in rows if r.get("target") is None and r.get("layer_other")],
        lambda r: ", ".join(f"`{v}`" for v in r["layer_other"]),
    )
    section(
        "Invalid cases whose target the model does not report",
        [r for r in rows if r.get("target") and r["outcome"] not in ("unsupported", "crash", "timeout")
         and r["target"] not in r.get("model", [])],
        lambda r: f"target `{r['target']}`",
    )
    print("\n".join(out))


if __name__ == "__main__":
    main()
