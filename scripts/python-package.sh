#!/usr/bin/env bash
# Builds and installs the Python package `instainpaint` into the project-local environment
# .venv-py (made here: Debian's python3 with its system packages visible, for python3-numpy and
# python3-torch, plus the pinned tools of python/requirements-dev.txt), the way a user would:
# pip install . (scikit-build-core, without build isolation, in `make build`'s folder build/,
# so only the module itself is compiled). Then, with --test, runs its tests.
#   scripts/python-package.sh [--test] [pytest arguments]
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${PYTHON_VENV:-.venv-py}
BUILD=${BUILD:-build}  # make build's folder
PYTHON=${PYTHON:-/usr/bin/python3}
say() { printf 'python-package: %s\n' "$*"; }

if [ ! -x "$VENV/bin/python" ]; then
  say "making $VENV ($PYTHON, system site packages visible)"
  "$PYTHON" -m venv --system-site-packages "$VENV"
fi
stamp="$VENV/.requirements-dev.txt"
if ! cmp -s python/requirements-dev.txt "$stamp"; then
  say "installing python/requirements-dev.txt"
  "$VENV/bin/pip" install --quiet --disable-pip-version-check -r python/requirements-dev.txt
  cp python/requirements-dev.txt "$stamp"
fi
say "pip install . (the module in build/, beside make build's libraries)"
# No build isolation: the pinned tools above build it, in make build's folder (an isolated build
# would find a cache from another environment there and start the folder afresh).
"$VENV/bin/pip" install --quiet --disable-pip-version-check --no-build-isolation --no-deps \
  --config-settings=build-dir="$BUILD" .
if [ "${1:-}" = "--test" ]; then
  shift
  say "tests (python/tests)"
  # From outside the source tree, so that `import instainpaint` is the installed package.
  build_dir=$(cd "$BUILD" && pwd)
  cd python/tests && INSTAINPAINT_CLI="$build_dir/instainpaint" INSTAINPAINT_BUILD_DIR="$build_dir" \
    exec "../../$VENV/bin/python" -m pytest -q "$@" .
fi
