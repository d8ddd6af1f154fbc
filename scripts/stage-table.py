#!/usr/bin/env python3
"""Prints where a command's time went: the stage table of eval's metrics.json, infer's run.json or a
serve job (GET /api/job), as the program recorded it (wall milliseconds per stage, calls, share of
what the caller waited for; stages "behind" ran beside the main work or after the answer).

Examples:
  scripts/stage-table.py out/eval/metrics.json
  scripts/stage-table.py out/infer/run.json --title "infer, statue, 256 high"
  curl -s -H "X-Instainpaint-Token: $TOKEN" http://127.0.0.1:8080/api/job | scripts/stage-table.py -
"""
import argparse
import json
import sys


def stage_rows(report):
    """The stages of a metrics.json, run.json or job object, and the total it gives (ms) or None."""
    stages = report.get("stages")
    if stages is None:
        sys.exit("stage-table: no \"stages\" in this JSON (an eval metrics.json, infer run.json or serve job)")
    total = report.get("total_ms") or report.get("timings", {}).get("total_ms")
    if total is None and "seconds" in report:
        total = 1000 * report["seconds"]
    return stages, total


def table(stages, total, title=None):
    waited = sum(s["ms"] for s in stages if not s.get("behind"))
    lines = [title] if title else []
    width = max([len(s["stage"]) for s in stages] + [24]) + 10
    lines.append(f"{'stage':<{width}} {'ms':>9} {'calls':>6} {'share':>7}")
    for s in stages:
        name = s["stage"] + (" (behind)" if s.get("behind") else "")
        share = "" if s.get("behind") or not waited else f"{100 * s['ms'] / waited:6.1f}%"
        lines.append(f"{name:<{width}} {s['ms']:>9.1f} {s['calls']:>6} {share:>7}")
    lines.append(f"{'sum of the stages waited for':<{width}} {waited:>9.1f}")
    if total is not None:
        lines.append(f"{'wall time of the whole':<{width}} {total:>9.1f}")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                     epilog="Examples:" + __doc__.split("Examples:")[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("json", help="the JSON file, or - for standard input")
    parser.add_argument("--title", help="a line printed above the table")
    args = parser.parse_args()
    try:
        text = sys.stdin.read() if args.json == "-" else open(args.json, encoding="utf-8").read()
        report = json.loads(text)
    except (OSError, json.JSONDecodeError) as error:
        sys.exit(f"stage-table: {args.json}: {error}")
    print(table(*stage_rows(report), title=args.title))


if __name__ == "__main__":
    main()
