# Shared by the scripts beside it: LaMa's generator taken out of a git mirror of
# github.com/advimman/lama, run under PyPI's torch in the project-local environment that the
# segmenter's reference scripts make (scripts/segmenter-reference/requirements.txt).
INPAINTER_REFERENCE_DIR=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
. "$INPAINTER_REFERENCE_DIR/../segmenter-reference/common.sh"

# extract_lama LAMA DEST: the saicinpainting package (its modules only; nothing is installed).
extract_lama() {
  mkdir -p "$2"
  extract_reference_package "$1" saicinpainting "$2"
}
