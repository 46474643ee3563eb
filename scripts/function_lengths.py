#!/usr/bin/env python3
"""Print the longest functions of C++ files: lines from the signature's first line to the
closing brace (lambdas count inside their function). Functions are found by the repository
checks' scanner, tests/cxx_scan.py.

usage: scripts/function_lengths.py [--max N] FILE...   (exit 1 if a function exceeds N)
"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
import cxx_scan  # noqa: E402


def lengths(path):
    """(lines, first line, qualified name) of every function body in the file."""
    src = cxx_scan.read(path)
    code = src.code
    out = []
    for f in cxx_scan.functions(src):
        # the signature starts after the previous statement, block or brace
        k = max(code.rfind(c, 0, f.start) for c in ";{}") + 1
        while k < f.start and code[k].isspace():
            k += 1
        first = src.line_of(k)
        out.append((src.line_of(f.end) - first + 1, first, f.name))
    return out


def main(argv):
    limit = None
    if len(argv) > 1 and argv[0] == "--max":
        limit = int(argv[1])
        argv = argv[2:]
    worst = sorted(((n, f"{p}:{first}", name) for p in argv for n, first, name in lengths(p)),
                   reverse=True)
    for n, where, name in worst[:10]:
        print(f"{n:5d}  {where}  {name}")
    if limit is not None and worst and worst[0][0] > limit:
        print(f"longest function is {worst[0][0]} lines (> {limit})")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
