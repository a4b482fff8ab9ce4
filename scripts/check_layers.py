#!/usr/bin/env python3
"""Fails when a module's file includes a header of a module it may not depend on.

Usage: check_layers.py SOURCE_DIR ROW...
Each ROW is "module|libraries|allowed,modules" as in cmake/layers.cmake (the test `layers` passes
that table). Every .h/.cpp under a module's folder belongs to the module whose folder is the
longest prefix of its directory; an include that names a file of the source tree (with "" or <>)
must belong to the same module or to one of the allowed ones. Prints one line per forbidden
include (file:line: the include, and what the module may use) and exits 1; exits 0 when none.
"""

import re
import sys
from pathlib import Path

INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]')
SUFFIXES = {".h", ".hpp", ".cpp", ".cc", ".inl"}


def module_of(path: str, modules):
    """The module whose folder is the longest prefix of `path`'s directory, or None."""
    parent = path.rsplit("/", 1)[0] if "/" in path else ""
    best = None
    for module in modules:
        if parent == module or parent.startswith(module + "/"):
            if best is None or len(module) > len(best):
                best = module
    return best


def main(argv):
    if len(argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    root = Path(argv[1]).resolve()
    allowed = {}
    for row in argv[2:]:
        module, _libraries, uses = row.split("|")
        allowed[module] = {m for m in uses.split(",") if m}
    modules = list(allowed)

    errors = []
    checked = 0
    for top in sorted({m.split("/")[0] for m in modules}):
        for file in sorted((root / top).rglob("*")):
            if file.suffix not in SUFFIXES or not file.is_file():
                continue
            rel = file.relative_to(root).as_posix()
            module = module_of(rel, modules)
            if module is None:
                continue
            checked += 1
            lines = file.read_text(encoding="utf-8", errors="replace").splitlines()
            for number, line in enumerate(lines, 1):
                match = INCLUDE.match(line)
                if not match or not (root / match.group(1)).is_file():
                    continue
                target = module_of(match.group(1), modules)
                if target == module or target in allowed[module]:
                    continue
                may = ", ".join(sorted(allowed[module])) or "nothing"
                errors.append(f"{rel}:{number}: #include \"{match.group(1)}\": {module}/ may not "
                              f"include {target or 'outside the modules'}/ (it may include: {may})")
    for error in errors:
        print(error)
    if errors:
        print(f"{len(errors)} forbidden include(s) in {checked} files; the arrows are in "
              "cmake/layers.cmake", file=sys.stderr)
        return 1
    print(f"layers: {checked} files, every include points down")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
