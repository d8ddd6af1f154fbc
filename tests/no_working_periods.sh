#!/bin/sh
# Fails when a tracked file names a working period (the word for one followed by a number) or a
# ticket of the project's own tracker ("issue" followed by a number, with or without '#'): a
# figure carries its date, commit and machine, a choice the requirement written out in words,
# which mean something to a reader. Another project's issue is allowed where the line gives its
# address: a line with "github.com" anywhere, or a line of CHANGELOG.md with a URL.
# Skipped (77) outside a git checkout. The words are spelt in two halves so that this file passes.
cd "${1:-.}" || exit 1
git rev-parse --is-inside-work-tree >/dev/null 2>&1 || { echo "skipped: not a git checkout"; exit 77; }
status=0
period="ses""sion"
found=$(git ls-files -z | xargs -0 grep -n -I -i -E "\\b${period}s? [0-9]+" 2>/dev/null)
if [ -n "$found" ]; then
  echo "$found"
  echo "these lines name a working period: give the date, commit and machine instead" >&2
  status=1
fi
ticket="is""sue"
found=$(git ls-files -z | xargs -0 grep -n -I -i -E "\\b${ticket}s?[ -]?#?[0-9]+" 2>/dev/null |
  grep -v -i "github\\.com" | grep -v -i -E "^([^:]*/)?CHANGELOG\\.md:[0-9]+:.*https?://")
if [ -n "$found" ]; then
  echo "$found"
  echo "these lines name a tracker's ticket: write out the requirement, or give the date, instead" >&2
  status=1
fi
[ "$status" -eq 0 ] && echo "no tracked file names a working period or a tracker's ticket"
exit "$status"
