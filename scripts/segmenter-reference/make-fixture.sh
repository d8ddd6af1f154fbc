#!/usr/bin/env bash
# Makes tests/segment/fixture/ again: small SAM and MobileSAM models with seeded random weights
# and the reference code's answers to a set of prompts (make_fixture.py says what is in it).
# SAM and MOBILE_SAM are git mirrors (or work trees) of github.com/facebookresearch/segment-anything
# and github.com/ChaoningZhang/MobileSAM; only their Python packages are extracted, to a temporary
# folder removed on exit. The reference code runs under PyPI's torch in the project-local
# .venv-sam-ref (requirements.txt beside this script; made on first use, about 4 GB with torch's
# NVIDIA packages). Nothing of theirs is copied into the repository.
#
#   scripts/segmenter-reference/make-fixture.sh SAM MOBILE_SAM [OUT]
# Example:
#   scripts/segmenter-reference/make-fixture.sh /work/.mirror/facebookresearch+segment-anything/repo \
#       /work/.mirror/ChaoningZhang+MobileSAM/repo
set -euo pipefail
if [ $# -lt 2 ] || [ "$1" = -h ] || [ "$1" = --help ]; then sed -n '2,13p' "$0"; exit 0; fi
HERE=$(cd "$(dirname "$0")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
OUT=${3:-$REPO/tests/segment/fixture}
VENV=${SAM_REF_VENV:-$REPO/.venv-sam-ref}
TMP=$(mktemp -d /tmp/segmenter-reference.XXXXXX)
trap 'rm -rf "$TMP"' EXIT

# $1: a work tree or a git directory; $2: the package folder in it; $3: where to put it.
extract() {
  if [ -d "$1/$2" ]; then cp -r "$1/$2" "$3/"; return; fi
  git --git-dir="$1" rev-parse -q --verify 'HEAD^{tree}' >/dev/null 2>&1 ||
    { echo "error: $1 is neither a work tree with $2/ nor a git directory" >&2; exit 1; }
  git --git-dir="$1" archive HEAD "$2" | tar -x -C "$3"
}
mkdir -p "$TMP/sam" "$TMP/mobile"
extract "$1" segment_anything "$TMP/sam"
extract "$2" mobile_sam "$TMP/mobile"

if [ ! -x "$VENV/bin/python" ]; then python3 -m venv "$VENV"; fi
"$VENV/bin/pip" install --quiet --disable-pip-version-check --only-binary=:all: -r "$HERE/requirements.txt"
"$VENV/bin/python" "$HERE/make_fixture.py" --segment-anything "$TMP/sam" --mobile-sam "$TMP/mobile" --out "$OUT"
ls -l "$OUT"
