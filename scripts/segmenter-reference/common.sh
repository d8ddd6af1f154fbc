# Shared by the scripts beside it: the reference packages taken out of git mirrors, and the
# project-local environment with PyPI's torch (requirements.txt) that runs them.
SEGMENTER_REFERENCE_DIR=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
SEGMENTER_REPO=$(cd "$SEGMENTER_REFERENCE_DIR/../.." && pwd)
SEGMENTER_VENV=${SAM_REF_VENV:-$SEGMENTER_REPO/.venv-sam-ref}

# extract SOURCE PACKAGE DEST: SOURCE a work tree or a git directory, PACKAGE its folder to copy.
extract_reference_package() {
  if [ -d "$1/$2" ]; then cp -r "$1/$2" "$3/"; return; fi
  git --git-dir="$1" rev-parse -q --verify 'HEAD^{tree}' >/dev/null 2>&1 ||
    { echo "error: $1 is neither a work tree with $2/ nor a git directory" >&2; exit 1; }
  # (a mirror may lack blobs outside the package: git warns about them, so its messages go)
  git --git-dir="$1" archive HEAD "$2" 2>/dev/null | tar -x -C "$3"
}

# The environment's python, made or brought up to date from requirements.txt.
reference_python() {
  if [ ! -x "$SEGMENTER_VENV/bin/python" ]; then python3 -m venv "$SEGMENTER_VENV" >&2; fi
  "$SEGMENTER_VENV/bin/pip" install --quiet --disable-pip-version-check --only-binary=:all: \
    -r "$SEGMENTER_REFERENCE_DIR/requirements.txt" >&2
  echo "$SEGMENTER_VENV/bin/python"
}

# extract_reference_packages SAM MOBILE_SAM DEST: both packages, DEST/sam/segment_anything and
# DEST/mobile/mobile_sam.
extract_reference_packages() {
  mkdir -p "$3/sam" "$3/mobile"
  extract_reference_package "$1" segment_anything "$3/sam"
  extract_reference_package "$2" mobile_sam "$3/mobile"
}
