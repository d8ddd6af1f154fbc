#!/usr/bin/env python3
"""The commands the README and docs/ show still exist: every `instainpaint COMMAND --option` in
their shell blocks names a command of the built binary and options its --help lists. (They are
examples on the reader's data, so they are checked, not run.)

  tests/docs_commands_test.py BINARY FILE.md [FILE.md ...]"""
import re
import shlex
import subprocess
import sys


def shell_lines(text):
    """The lines of ```sh blocks, continuation lines joined."""
    out, inside, pending = [], False, ""
    for line in text.splitlines():
        if line.startswith("```"):
            inside = line.strip() in ("```sh", "```bash", "```shell") if not inside else False
            continue
        if not inside:
            continue
        pending += line.rstrip()
        if pending.endswith("\\"):
            pending = pending[:-1] + " "
            continue
        out.append(pending.split(" #")[0])
        pending = ""
    return out


def commands(line):
    """(command, options) for each instainpaint call on the line."""
    try:
        words = shlex.split(line, comments=True)
    except ValueError:
        words = line.split()
    found = []
    for i, w in enumerate(words):
        # The program itself, not an argument of another (a script handed the binary's path).
        starts = i == 0 or words[i - 1] in ("|", "&&", ";", "time", "nice", "env") or re.match(r"^\w+=", words[i - 1])
        if starts and re.fullmatch(r"(.*/)?instainpaint", w) and i + 1 < len(words) and not words[i + 1].startswith("-"):
            opts = []
            for v in words[i + 2:]:
                if v in ("|", "&&", ";", ">", "2>"):
                    break
                if v.startswith("--"):
                    opts.append(v.split("=")[0])
            found.append((words[i + 1], opts))
    return found


def main():
    binary, files = sys.argv[1], sys.argv[2:]
    helps, problems, checked = {}, [], 0
    for path in files:
        for line in shell_lines(open(path, encoding="utf-8").read()):
            for command, opts in commands(line):
                if command not in helps:
                    run = subprocess.run([binary, command, "--help"], capture_output=True, text=True)
                    # An unknown command prints the program's own help: its usage line names no command.
                    own = re.search(r"Usage: \S*instainpaint " + re.escape(command) + r"\b", run.stdout)
                    helps[command] = run.stdout if run.returncode == 0 and own else None
                if helps[command] is None:
                    problems.append(f"{path}: `{command}` is not a command ({line.strip()})")
                    continue
                for opt in opts:
                    checked += 1
                    if not re.search(re.escape(opt) + r"(?![\w-])", helps[command]):
                        problems.append(f"{path}: `{command}` has no option {opt} ({line.strip()})")
    for p in problems:
        print(p)
    print(f"{checked} options of {len(helps)} commands checked in {len(files)} files, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
