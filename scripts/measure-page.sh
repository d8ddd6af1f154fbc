#!/usr/bin/env bash
# The page's timings that its browser tests only print (page load to first frame, locally and
# over an emulated 50 Mbit/s link; the software-GL frame rate; Run and Fill to splats on screen):
# the browser tests with INSTAINPAINT_MEASURE=1, alone on the machine, their "measured:" lines.
#   scripts/measure-page.sh [BUILD]      (default build; make build first)
set -euo pipefail
cd "$(dirname "$0")/.."
cli=${1:-build}/instainpaint
[ -x "$cli" ] || { echo "measure-page: no $cli (make build first)" >&2; exit 2; }
for test in view edit fill; do
  INSTAINPAINT_MEASURE=1 node "tests/web/browser/$test.test.mjs" "$cli" | grep '^measured:' | sed "s/^/$test: /"
done
