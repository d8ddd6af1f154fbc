#!/usr/bin/env bash
# Makes tests/inpaint/fixture/ again: a small LaMa generator (big-lama's layout: FFC-ResNet,
# fast Fourier convolutions on three quarters of the channels) with seeded random weights, saved
# as PyTorch Lightning saves big-lama's best.ckpt (the generator beside other weights, the
# callbacks' classes as keys), and the reference code's inpainting of two photos, one of a size
# that is not a multiple of 8 (make_fixture.py says what is in it). LAMA is a git mirror (or a
# work tree) of github.com/advimman/lama; only its saicinpainting package is extracted, to a
# temporary folder removed on exit. Nothing of theirs is copied into the repository.
#
#   scripts/inpainter-reference/make-fixture.sh LAMA [OUT]
# Example:
#   scripts/inpainter-reference/make-fixture.sh /work/.mirror/advimman+lama/repo
set -euo pipefail
if [ $# -lt 1 ] || [ "$1" = -h ] || [ "$1" = --help ]; then sed -n '2,12p' "$0"; exit 0; fi
. "$(dirname "$0")/common.sh"
OUT=${2:-$SEGMENTER_REPO/tests/inpaint/fixture}
TMP=$(mktemp -d /tmp/inpainter-reference.XXXXXX)
trap 'rm -rf "$TMP"' EXIT
extract_lama "$1" "$TMP/lama"
PYTHON=$(reference_python)
"$PYTHON" "$INPAINTER_REFERENCE_DIR/make_fixture.py" --lama "$TMP/lama" --out "$OUT"
ls -lR "$OUT"
