#!/usr/bin/env bash
# The main job of `make demo`. For now: read a real SPIn-NeRF scene, build the network's
# inputs, write a report to demo-out/.
set -euo pipefail
BIN=${1:-build/instainpaint}
SHARED=${SHARED:-../shared}
SCENE="$SHARED/data/statue"
if [ ! -d "$SCENE" ]; then
  echo "demo: $SCENE not found (the shared data folder sits beside the repository)" >&2
  exit 1
fi
"$BIN" scene-info --scene "$SCENE"
"$BIN" prepare --scene "$SCENE" --out demo-out
echo
echo "demo-out/report.json: what was read and built; demo-out/inputs/: the four views as the network sees them"
