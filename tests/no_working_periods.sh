#!/bin/sh
# Fails when a tracked file names a working period (the word for one followed by a number): a
# figure carries its date, commit and machine instead, which mean something to a reader.
# Skipped (77) outside a git checkout. The word is spelt in two halves so that this file passes.
cd "${1:-.}" || exit 1
git rev-parse --is-inside-work-tree >/dev/null 2>&1 || { echo "skipped: not a git checkout"; exit 77; }
word="ses""sion"
found=$(git ls-files -z | xargs -0 grep -n -I -i -E "\\b${word}s? [0-9]+" 2>/dev/null)
if [ -n "$found" ]; then
  echo "$found"
  echo "these lines name a working period: give the date, commit and machine instead" >&2
  exit 1
fi
echo "no tracked file names a working period"
