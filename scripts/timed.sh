#!/usr/bin/env bash
# Runs a command and says how long it took: each step of `make test` (and so of CI) prints
# its own time, so that a slow run shows where the time went.
#   scripts/timed.sh NAME COMMAND [ARGUMENTS...]
name=$1
shift
start=$SECONDS
"$@"
status=$?
echo "time: $name took $((SECONDS - start)) s$([ $status = 0 ] || echo " (failed: exit $status)")"
exit $status
