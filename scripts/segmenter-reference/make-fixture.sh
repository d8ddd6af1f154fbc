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
. "$(dirname "$0")/common.sh"
OUT=${3:-$SEGMENTER_REPO/tests/segment/fixture}
TMP=$(mktemp -d /tmp/segmenter-reference.XXXXXX)
trap 'rm -rf "$TMP"' EXIT
extract_reference_packages "$1" "$2" "$TMP"
PYTHON=$(reference_python)
STATUE=${INSTAINPAINT_SHARED:-$SEGMENTER_REPO/../shared}/data/statue
"$PYTHON" "$SEGMENTER_REFERENCE_DIR/make_fixture.py" --segment-anything "$TMP/sam" --mobile-sam "$TMP/mobile" \
  --out "$OUT" --statue "$STATUE"
ls -l "$OUT"
