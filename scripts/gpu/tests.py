#!/usr/bin/env python3
"""The tests the PyPI LibTorch build runs, from tests/pypi_build.list (its header says why).

  scripts/gpu/tests.py --regex            the ctest -R expression of the list's prefixes
  scripts/gpu/tests.py --check BUILD_DIR  fails, naming the line or the file, when the list
                                          misses a source that can differ between LibTorch
                                          versions, names a missing source, or has a prefix
                                          that matches no test of BUILD_DIR
"""
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
LIST = REPO / "tests" / "pypi_build.list"

# What makes a source's behaviour depend on the LibTorch it is built against.
VERSION_DEPENDENT = re.compile(
    r'#include "common/torch_compat\.h"|\bII_TORCH2\b|\bII_HAS_CUDA_TORCH\b|\bII_HAS_C10D_\w+|'
    r'\bII_TCPSTORE_\w+|\bis_cuda\(\)|\btorch::cuda::|\bat::cuda::|\bc10::cuda::|\bkCUDA\b')


def read_list():
    groups = []
    for number, line in enumerate(LIST.read_text().splitlines(), 1):
        line = line.split("#", 1)[0].split()
        if line:
            groups.append((number, line[0], line[1:]))
    return groups


def sources_that_can_differ():
    found = set()
    for path in sorted((REPO / "src").rglob("*")):
        if path.suffix not in (".cpp", ".cu"):
            continue
        relative = path.relative_to(REPO).as_posix()
        kernel = path.suffix == ".cu" or re.search(r"(kernels|raster_tiles|region_weights)_\w+\.cpp$", relative)
        if kernel or VERSION_DEPENDENT.search(path.read_text(errors="replace")):
            found.add(relative)
    return found


def check(build_dir):
    problems = []
    groups = read_list()
    named = set()
    for number, _, sources in groups:
        for source in sources:
            named.add(source)
            if not (REPO / source).is_file():
                problems.append(f"{LIST}:{number}: {source} does not exist")
    for source in sorted(sources_that_can_differ() - named):
        problems.append(f"{LIST}: {source} can differ between LibTorch versions (torch_compat.h, CUDA or a "
                        "kernel) but no line names it: add the tests that cover it")
    listed = subprocess.run(["ctest", "-N"], cwd=build_dir, capture_output=True, text=True, check=True).stdout
    tests = re.findall(r"Test +#\d+: (\S+)", listed)

    def listed_by(prefix):
        return {test for test in tests if test == prefix or test.startswith(prefix + ".")}

    wanted = set()
    for number, prefix, _ in groups:
        if not listed_by(prefix):
            problems.append(f"{LIST}:{number}: the prefix '{prefix}' matches no test of {build_dir}")
        wanted |= listed_by(prefix)
    # What ctest itself selects with the expression build.sh gives it (ctest runs nothing, and
    # succeeds, when it cannot compile an expression).
    selected = subprocess.run(["ctest", "-N", "-R", regex()], cwd=build_dir, capture_output=True, text=True,
                              check=True).stdout
    selected = set(re.findall(r"Test +#\d+: (\S+)", selected))
    if selected != wanted:
        problems.append(f"ctest -R selects {len(selected)} tests, the list names {len(wanted)}: "
                        f"{sorted(selected ^ wanted)[:5]}")
    for problem in problems:
        print(problem)
    return 1 if problems else 0


def regex():
    # ctest's own regular expressions (no more than 9 groups, so none): a prefix is a whole
    # name or a name's first parts.
    names = [prefix.replace(".", "[.]") for _, prefix, _ in read_list()]
    return "|".join(f"^{name}$|^{name}[.]" for name in names)


def main():
    if len(sys.argv) == 2 and sys.argv[1] == "--regex":
        print(regex())
        return 0
    if len(sys.argv) == 3 and sys.argv[1] == "--check":
        return check(sys.argv[2])
    print(__doc__.strip(), file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
