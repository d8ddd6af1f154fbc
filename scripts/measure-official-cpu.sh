#!/usr/bin/env bash
# Times the official InstaInpaint network's forward pass on the CPU (random weights), for
# comparison on the same machine with
#   build/instainpaint bench --presets release --sizes 256 --baseline none
# OFFICIAL is a checkout of github.com/dhmbb2/InstaInpaint: a work tree, or a bare git
# directory whose instainpaint/ folder is extracted to a temporary folder (removed on exit).
# The official code is never copied into this project. Other arguments go to
# scripts/official_cpu_forward.py (--views 4 --size 256 --threads 2 --repeat 2 --precision bf16).
# Needs python3 with torch (Debian: apt-get install python3-torch); $PYTHON picks the interpreter.
#
#   scripts/measure-official-cpu.sh OFFICIAL [--views V] [--size S] [--threads T] [--repeat R]
#       [--precision bf16|fp32]
# Example:
#   scripts/measure-official-cpu.sh /work/.mirror/dhmbb2+InstaInpaint/repo --threads 2 --repeat 2
set -euo pipefail
if [ $# -lt 1 ] || [ "$1" = -h ] || [ "$1" = --help ]; then sed -n '2,14p' "$0"; exit 0; fi
OFFICIAL=$1; shift
HERE=$(cd "$(dirname "$0")" && pwd)

if [ -z "${PYTHON:-}" ]; then
  for p in python3 /usr/bin/python3; do
    if command -v "$p" >/dev/null && "$p" -c 'import torch' 2>/dev/null; then PYTHON=$p; break; fi
  done
fi
if [ -z "${PYTHON:-}" ] || ! "$PYTHON" -c 'import torch' 2>/dev/null; then
  echo "error: no python3 that can import torch (install it: apt-get install python3-torch, or set PYTHON)" >&2
  exit 1
fi

if [ ! -d "$OFFICIAL/instainpaint" ]; then
  if ! git --git-dir="$OFFICIAL" rev-parse -q --verify 'HEAD^{tree}' >/dev/null 2>&1; then
    echo "error: $OFFICIAL is neither an official work tree (with instainpaint/) nor a bare git dir" >&2
    exit 1
  fi
  TMP=$(mktemp -d /tmp/instainpaint-official.XXXXXX)
  trap 'rm -rf "$TMP"' EXIT
  # Only the Python package: a mirror may lack the large asset blobs, which breaks a full
  # archive (git then still warns about them, so its messages are shown only on failure).
  git --git-dir="$OFFICIAL" archive -o "$TMP/src.tar" HEAD instainpaint 2>"$TMP/git.err" ||
    { cat "$TMP/git.err" >&2; exit 1; }
  tar -x -C "$TMP" -f "$TMP/src.tar"
  OFFICIAL=$TMP
fi
"$PYTHON" "$HERE/official_cpu_forward.py" --official "$OFFICIAL" "$@"
