#!/usr/bin/env python3
"""Times the phases of a whole command as the user waits for it: from the start to its first line
of output (loading the program's libraries, setting up the device), from there to its last line
(the work, which the command's own stage table details: scripts/stage-table.py), and from the
last line to its exit (tearing down). Its output is passed through.

Examples:
  scripts/command-phases.py -- build/instainpaint eval --scene ../shared/data/statue --hold-out-every 8
  scripts/command-phases.py --quiet -- build-gpu/instainpaint infer --device cuda --scene room --out /tmp/x
"""
import argparse
import subprocess
import sys
import time


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                     epilog="Examples:" + __doc__.split("Examples:")[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quiet", action="store_true", help="do not pass the command's output through")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="the command, after --")
    args = parser.parse_args()
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("no command given (put it after --)")
    start = time.perf_counter()
    try:
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, bufsize=0)
    except OSError as error:
        sys.exit(f"command-phases: cannot start {command[0]}: {error}")
    first = last = None
    for line in iter(process.stdout.readline, b""):
        now = time.perf_counter()
        first = first if first is not None else now
        last = now
        if not args.quiet:
            sys.stdout.write(line.decode(errors="replace"))
    code = process.wait()
    end = time.perf_counter()
    if first is None:
        first = last = end
    print(f"phases (ms): start to first line {1000 * (first - start):.0f}, first to last line "
          f"{1000 * (last - first):.0f}, last line to exit {1000 * (end - last):.0f}; whole {1000 * (end - start):.0f}"
          f" (exit code {code})")
    sys.exit(code)


if __name__ == "__main__":
    main()
