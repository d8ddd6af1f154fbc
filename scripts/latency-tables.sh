#!/usr/bin/env bash
# Where the time of an edit and of an evaluation goes on this machine: one `serve` edit timed the
# page's way (scripts/measure-serve-edit.py: Run to the new splats' last byte, then the server's
# stage table) and one `eval` (the whole command's phases, scripts/command-phases.py, then its
# stage table, scripts/stage-table.py), on a real scene.
#
#   scripts/latency-tables.sh                                  # build/instainpaint, statue, 256 high, CPU
#   scripts/latency-tables.sh --bin build-gpu/instainpaint --height 512 -- --device cuda
#
# Options: --bin PROGRAM, --scene DIR (with object masks; default ../shared/data/statue),
# --height ROWS (default 256), --runs N edits (default 3); after --, options for both commands.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=build/instainpaint SCENE=../shared/data/statue HEIGHT=256 RUNS=3
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --scene) SCENE=$2; shift 2 ;;
    --height) HEIGHT=$2; shift 2 ;;
    --runs) RUNS=$2; shift 2 ;;
    --) shift; break ;;
    -h|--help) sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "latency-tables: unknown option $1 (see --help)" >&2; exit 2 ;;
  esac
done
[ -x "$BIN" ] || { echo "latency-tables: no program at $BIN (make build, or --bin)" >&2; exit 2; }
[ -d "$SCENE" ] || { echo "latency-tables: no scene at $SCENE (--scene)" >&2; exit 2; }
OUT=$(mktemp -d -t ii-latency-XXXXXX)
trap 'rm -rf "$OUT"' EXIT

echo "== serve: an edit, $HEIGHT high ($SCENE)"
python3 scripts/measure-serve-edit.py --bin "$BIN" --scene "$SCENE" --runs "$RUNS" -- --height "$HEIGHT" "$@"

echo
echo "== eval: every 8th view held out, $HEIGHT high ($SCENE)"
python3 scripts/command-phases.py --quiet -- "$BIN" eval --scene "$SCENE" --hold-out-every 8 --height "$HEIGHT" \
  --out "$OUT/eval" "$@"
python3 scripts/stage-table.py "$OUT/eval/metrics.json"
