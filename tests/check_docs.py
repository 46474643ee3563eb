#!/usr/bin/env python3
"""Check that the manual stays true to the tree.

1. docs/dev/code_layout.md lists every source file of the code's folders (cxx_scan.LAYERS:
   *.cpp, *.hpp) exactly once, and no file that does not exist. A bullet names files as
   `folder/name.cpp`, or `folder/name.{hpp,cpp}` for a unit of several.
2. Nothing in the repository's text (Markdown, C++, Python, shell, CMake, JSON) points to a
   file outside it: no `../shared`, `DESIGN.md`, `VALIDATION.md`, `STYLE.md` or `seeds/`.
3. Every relative link of README.md and docs/**/*.md, [text](path) or [text](path#anchor),
   resolves to a file or folder of the repository.

Usage: check_docs.py SOURCE_DIR   (exit 1 and one line per problem)
       check_docs.py --self-test
"""

import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cxx_scan  # noqa: E402

LAYOUT = os.path.join("docs", "dev", "code_layout.md")
OUTSIDE = re.compile(r"\.\./shared|\bDESIGN\.md|\bVALIDATION\.md|\bSTYLE\.md|\bseeds/")
TEXT_EXT = (".md", ".cpp", ".hpp", ".py", ".sh", ".txt", ".cmake", ".json")
SKIP_DIRS = {".git", "build", "build-sanitize", "out"}
# A file path in backticks, possibly with one {a,b} group: `fluid/grid/grid.{hpp,cpp}`.
PATH = re.compile(r"`([A-Za-z0-9_./-]+?)(?:\{([A-Za-z0-9_,.]+)\})?`")
LINK = re.compile(r"\]\(([^)\s]+)\)")


def source_files(root):
    found = set()
    for layer in cxx_scan.LAYERS:
        for dirpath, dirnames, filenames in os.walk(os.path.join(root, layer)):
            dirnames.sort()
            for f in filenames:
                if f.endswith((".cpp", ".hpp")):
                    found.add(os.path.relpath(os.path.join(dirpath, f), root))
    return found


def listed_files(text):
    """(path, line) of every file the layout's bullets name (first backticked path only)."""
    out = []
    for n, line in enumerate(text.splitlines(), 1):
        if not line.lstrip().startswith(("- ", "* ")):
            continue
        for m in PATH.finditer(line):
            stem, group = m.group(1), m.group(2)
            if group:
                out += [(stem + ext, n) for ext in group.split(",")]
            elif stem.endswith((".cpp", ".hpp")):
                out.append((stem, n))
    return out


def check_layout(root):
    path = os.path.join(root, LAYOUT)
    if not os.path.exists(path):
        return [f"{LAYOUT}: missing (the code layout, every source file once)"]
    with open(path, encoding="utf-8") as f:
        listed = listed_files(f.read())
    errors, seen = [], {}
    have = source_files(root)
    for p, n in listed:
        if p in seen:
            errors.append(f"{LAYOUT}:{n}: {p} listed twice (first on line {seen[p]})")
        seen.setdefault(p, n)
        if p not in have:
            errors.append(f"{LAYOUT}:{n}: {p} does not exist: remove it or fix the path")
    for p in sorted(have - set(seen)):
        errors.append(f"{LAYOUT}: {p} is not listed: add a line for it")
    return errors


def text_files(root):
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if d not in SKIP_DIRS)
        for f in sorted(filenames):
            if f.endswith(TEXT_EXT) or f in ("Makefile", "CMakeLists.txt", "run"):
                yield os.path.join(dirpath, f)


def check_outside(root):
    errors = []
    me = os.path.abspath(__file__)
    for full in text_files(root):
        if os.path.abspath(full) == me:
            continue
        with open(full, encoding="utf-8", errors="replace") as f:
            for n, line in enumerate(f, 1):
                m = OUTSIDE.search(line)
                if m:
                    errors.append(f"{os.path.relpath(full, root)}:{n}: '{m.group(0)}' points "
                                  "outside the repository: cite the docs/ page or the paper")
    return errors


def markdown_files(root):
    yield os.path.join(root, "README.md")
    for dirpath, dirnames, filenames in os.walk(os.path.join(root, "docs")):
        dirnames.sort()
        for f in sorted(filenames):
            if f.endswith(".md"):
                yield os.path.join(dirpath, f)


def check_links(root):
    errors = []
    for full in markdown_files(root):
        if not os.path.exists(full):
            continue
        with open(full, encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                for m in LINK.finditer(line):
                    target = m.group(1).split("#")[0]
                    if not target or re.match(r"^[a-z]+:", target):
                        continue  # an anchor in the page, or a URL
                    to = os.path.normpath(os.path.join(os.path.dirname(full), target))
                    if not os.path.exists(to) or not to.startswith(os.path.abspath(root)):
                        errors.append(f"{os.path.relpath(full, root)}:{n}: link '{m.group(1)}' "
                                      "does not resolve to a file of the repository")
    return errors


def check(root):
    root = os.path.abspath(root)
    return check_layout(root) + check_outside(root) + check_links(root)


def self_test():
    layout_ok = "# Layout\n- `core/a.{hpp,cpp}` — a\n- `mesh/b.cpp` — b\n"
    base = {"core/a.hpp": "", "core/a.cpp": "", "mesh/b.cpp": "", "README.md": "# r\n"}
    cases = [
        ("clean", {**base, LAYOUT: layout_ok}, []),
        ("a file not listed", {**base, "mesh/c.hpp": "", LAYOUT: layout_ok},
         [f"{LAYOUT}: mesh/c.hpp is not listed"]),
        ("a listed file gone", {**base, LAYOUT: layout_ok + "- `solid/d.cpp` — d\n"},
         [f"{LAYOUT}:4: solid/d.cpp does not exist"]),
        ("listed twice", {**base, LAYOUT: layout_ok + "- `mesh/b.cpp` — again\n"},
         [f"{LAYOUT}:4: mesh/b.cpp listed twice"]),
        ("points outside", {**base, LAYOUT: layout_ok, "core/a.cpp": "// see DESIGN.md\n"},
         ["core/a.cpp:1: 'DESIGN.md' points outside"]),
        ("a broken link", {**base, LAYOUT: layout_ok,
                           "README.md": "[m](docs/user/nope.md) [ok](docs/dev/code_layout.md)\n"},
         ["README.md:1: link 'docs/user/nope.md' does not resolve"]),
    ]
    return cxx_scan.self_test_trees(cases, check)


def main(argv):
    return cxx_scan.check_main(argv, "check_docs.py", check, self_test,
                               "docs: the code layout lists every source file, nothing points outside, links resolve",
                               "{n} problem(s) between the docs and the tree")


if __name__ == "__main__":
    sys.exit(main(sys.argv))
