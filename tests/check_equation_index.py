#!/usr/bin/env python3
"""Check REFERENCES.md's equation index against the `[Key, Eq. (n)]` tags in the code.

Usage: check_equation_index.py SOURCE_DIR   (exit 1 and one line per violation)
       check_equation_index.py --self-test  (runs the checks on small made-up trees)

The convention it enforces is written in REFERENCES.md, "Equation index".
"""

import os
import re
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cxx_scan  # noqa: E402

ROW = re.compile(r"^\|\s*(\w+)\s+\((\d+)\)\s*\|")
DEFINED = ("derivation only", "not used")


def split_row(line):
    cells = re.split(r"(?<!\\)\|", line.strip())
    return [c.strip() for c in cells[1:-1]]


class Entry:
    def __init__(self, key, eq, file, function, line):
        self.key, self.eq, self.file, self.function, self.line = key, eq, file, function, line

    def label(self):
        return f"{self.key} ({self.eq})"


def read_index(root, errors):
    """{(key, n): Entry} from the table of REFERENCES.md's "## Equation index" section."""
    path = os.path.join(root, "REFERENCES.md")
    try:
        lines = open(path, encoding="utf-8").read().split("\n")
    except OSError as e:
        errors.append(f"REFERENCES.md: cannot read it ({e.strerror})")
        return {}
    index, in_section = {}, False
    for no, line in enumerate(lines, 1):
        if line.startswith("## "):
            in_section = line.strip() == "## Equation index"
            continue
        m = ROW.match(line) if in_section else None
        if not m:
            continue
        cells = split_row(line)
        where = f"REFERENCES.md:{no}"
        if len(cells) != 4:
            errors.append(f"{where}: expected 4 columns (equation | file | implemented by | "
                          f"what), got {len(cells)}")
            continue
        key, eq = m.group(1), int(m.group(2))
        file, impl = cells[1].strip("`"), cells[2]
        if impl in DEFINED:
            if file not in ("—", "-", ""):
                errors.append(f"{where}: {key} ({eq}) is '{impl}' but names a file ({file}); "
                              f"write — in the file column")
            entry = Entry(key, eq, None, None, no)
        elif impl.startswith("`") and impl.endswith("`") and file.endswith(".cpp"):
            entry = Entry(key, eq, file, impl.strip("`"), no)
        else:
            errors.append(f"{where}: {key} ({eq}): the implementing column must be `qualified::"
                          f"name` with a .cpp file, or 'derivation only' / 'not used'")
            continue
        if (key, eq) in index:
            errors.append(f"{where}: {key} ({eq}) has a second row (first at line "
                          f"{index[(key, eq)].line})")
            continue
        index[(key, eq)] = entry
    if not index:
        errors.append("REFERENCES.md: no rows found under '## Equation index'")
    for key in sorted({k for k, _ in index}):
        nums = sorted(n for k, n in index if k == key)
        missing = sorted(set(range(1, nums[-1] + 1)) - set(nums))
        if missing:
            errors.append(f"REFERENCES.md: {key}: no rows for equation(s) "
                          f"{', '.join(map(str, missing))} (every equation from (1) needs one)")
    return index


def tag_equations(body):
    """Equation numbers named by the text after the key of a tag ('Eqs. (4)–(5), (9)')."""
    m = re.search(r"\bEqs?\.", body)
    if not m:
        return []
    out = []
    for a, b in re.findall(r"\((\d+)\)(?:\s*[–-]\s*\((\d+)\))?", body[m.end():]):
        lo, hi = int(a), int(b or a)
        out.extend(range(lo, hi + 1) if hi >= lo else [lo])
    return out


def comment_blocks(src):
    """Comments as blocks, consecutive line comments (on consecutive lines) joined by a space:
    [(text, offsets)] with offsets[i] the file offset of text[i]."""
    blocks = []  # [text, offsets, end offset, is line comment]
    for off, raw in src.comments:
        if not raw.startswith("//"):
            blocks.append([raw, list(range(off, off + len(raw))), off + len(raw), False])
            continue
        body = raw.lstrip("/").lstrip("!<")
        start = off + len(raw) - len(body)
        prev = blocks[-1] if blocks else None
        gap = src.text[prev[2]:off] if prev else ""
        if prev and prev[3] and gap.strip() == "" and gap.count("\n") == 1:
            prev[0] += " " + body
            prev[1] += [start] + list(range(start, start + len(body)))
            prev[2] = off + len(raw)
        else:
            blocks.append([body, list(range(start, start + len(body))), off + len(raw), True])
    return [(text, offsets) for text, offsets, _, _ in blocks]


class Tag:
    def __init__(self, path, line, text, key, eqs, offset, cited, in_comment):
        self.path, self.line, self.text, self.key, self.eqs = path, line, text, key, eqs
        self.offset, self.cited, self.in_comment = offset, cited, in_comment


def find_tags(src, rel, keys):
    pattern = re.compile(r"\[(" + "|".join(map(re.escape, keys)) + r")\b([^\[\]]*)\]")
    tags = []
    sources = [(text, offs, True) for text, offs in comment_blocks(src)]
    sources += [(s, list(range(off, off + len(s))), False) for off, s in src.strings]
    for text, offs, in_comment in sources:
        for m in pattern.finditer(text):
            before = text[:m.start()]
            cited = re.search(r"\bsee(\s+also)?\s*$", before, re.IGNORECASE) is not None
            off = offs[m.start()]
            tags.append(Tag(rel, src.line_of(off), " ".join(m.group(0).split()), m.group(1),
                            tag_equations(m.group(2)), off, cited or not in_comment, in_comment))
    return tags


def scanned_files(root):
    for top in cxx_scan.LAYERS + ["tests"]:
        base = os.path.join(root, top)
        for dirpath, dirnames, filenames in os.walk(base):
            dirnames.sort()
            for f in sorted(filenames):
                if f.endswith((".cpp", ".hpp")):
                    full = os.path.join(dirpath, f)
                    yield os.path.relpath(full, root), full


def check(root):
    errors = []
    index = read_index(root, errors)
    keys = sorted({k for k, _ in index})
    if not keys:
        return errors
    implementing = {}  # (key, n) -> [(tag, function name)]
    defined = {}  # rel path -> {qualified names}
    for rel, full in scanned_files(root):
        src = cxx_scan.read(full)
        funcs = cxx_scan.functions(src) if rel.endswith(".cpp") else []
        defined[rel] = {f.name for f in funcs}
        is_site_file = rel.endswith(".cpp") and rel.split(os.sep)[0] in cxx_scan.LAYERS
        for tag in find_tags(src, rel, keys):
            for n in tag.eqs:
                if (tag.key, n) not in index:
                    errors.append(f"{rel}:{tag.line}: {tag.text} names {tag.key} ({n}), which "
                                  f"the equation index in REFERENCES.md does not list")
            if not is_site_file or tag.cited:
                continue
            inside = [f for f in funcs if f.contains(tag.offset)]
            if not inside:
                continue
            for n in tag.eqs:
                if (tag.key, n) in index:
                    implementing.setdefault((tag.key, n), []).append((tag, inside[-1].name))
    misplaced = {}  # id(tag) -> (tag, fn, [what the index says, per equation])
    for (key, n), entry in sorted(index.items()):
        sites = implementing.get((key, n), [])
        if entry.function is not None:
            names = defined.get(entry.file)
            if names is None:
                errors.append(f"REFERENCES.md:{entry.line}: {entry.label()}: {entry.file} does "
                              f"not exist (or is not under {', '.join(cxx_scan.LAYERS)})")
                continue
            if entry.function not in names:
                errors.append(f"REFERENCES.md:{entry.line}: {entry.label()}: no definition of "
                              f"{entry.function} in {entry.file}")
                continue
        home = (entry.file, entry.function)
        for tag, fn in sites:
            if (tag.path, fn) != home:
                says = (f"({n}) is {entry.function} in {entry.file}" if entry.function else
                        f"({n}) has none")
                misplaced.setdefault(id(tag), (tag, fn, []))[2].append(says)
        if entry.function and not any((t.path, fn) == home for t, fn in sites):
            others = sorted({fn for _, fn in sites})
            hint = f" (tagged instead in {', '.join(others)})" if others else ""
            errors.append(f"REFERENCES.md:{entry.line}: {entry.label()}: no implementing tag "
                          f"inside {entry.function} ({entry.file}){hint}; add a comment "
                          f"[{key}, Eq. ({n})] on the code that computes it")
    for tag, fn, says in sorted(misplaced.values(), key=lambda v: (v[0].path, v[0].line)):
        errors.append(f"{tag.path}:{tag.line}: {tag.text} is an implementing site in {fn}, but "
                      f"the index's implementing site of {'; of '.join(says)}; write `see "
                      f"{tag.text}` if this code only uses or mentions it, or remove the "
                      f"duplicate")
    return errors


# ---- self-test: each failure mode on a made-up tree, and a clean tree -------------------------

INDEX = """# References

## Equation index

| equation | file | implemented by | what |
|---|---|---|---|
| Paper99 (1) | `solid/a.cpp` | `ns::Body::step` | one |
| Paper99 (2) | — | derivation only | two |
| Paper99 (3) | `solid/a.cpp` | `ns::helper` | three \\| with a pipe |
"""

CLEAN = {
    "solid/a.cpp": """// File comment citing [Paper99, Eq. (2)].
namespace ns {
namespace {
/// doc of a file-local function [Paper99, Eq. (1)]
int helper(int x) {
  return x + 1;  // [Paper99, Eq. (3)]
}
}  // namespace
struct Body {
  int f() const { return 0; }
};
int Body::step(const std::function<int(int)>& g) const {
  // x = y + z  [Paper99,
  // Eq. (1)]
  auto l = [&](int k) { return helper(k); };  // see [Paper99, Eq. (3)]
  throw Error("bad [Paper99, Eq. (2)]");
}
}  // namespace ns
""",
    "solid/a.hpp": "/// [Paper99, Eqs. (1)–(3)]\nint f() { return 1; }  // [Paper99, Eq. (1)]\n",
    "tests/t.cpp": "void t() {\n  // [Paper99, Eq. (3)]\n}\n",
}


def self_test():
    def run(files, index=INDEX):
        with tempfile.TemporaryDirectory() as d:
            for rel, text in dict(CLEAN, **files).items():
                if text is None:
                    continue
                os.makedirs(os.path.dirname(os.path.join(d, rel)), exist_ok=True)
                with open(os.path.join(d, rel), "w", encoding="utf-8") as f:
                    f.write(text)
            with open(os.path.join(d, "REFERENCES.md"), "w", encoding="utf-8") as f:
                f.write(index)
            return check(d)

    cases = [
        ("clean tree", {}, INDEX, []),
        ("unknown equation", {"tests/t.cpp": "// [Paper99, Eqs. (3)-(4)]\n"}, INDEX,
         ["tests/t.cpp:1: [Paper99, Eqs. (3)-(4)] names Paper99 (4), which the equation index"]),
        ("second site", {"coupling/c.cpp": "namespace ns {\nvoid g() {\n  x += 1;  "
                         "// [Paper99, Eq. (1)]\n}\n}\n"}, INDEX,
         ["coupling/c.cpp:3: [Paper99, Eq. (1)] is an implementing site in ns::g, but the "
          "index's implementing site of (1) is ns::Body::step in solid/a.cpp"]),
        ("site of a derivation-only equation", {"run/d.cpp": "void g() {\n/* [Paper99, "
                                                "Eq. (2)] */\n}\n"}, INDEX,
         ["run/d.cpp:2: [Paper99, Eq. (2)] is an implementing site in g, but the index's "
          "implementing site of (2) has none"]),
        ("function gone", {}, INDEX.replace("ns::helper", "ns::helper2"),
         ["REFERENCES.md:9: Paper99 (3): no definition of ns::helper2 in solid/a.cpp"]),
        ("file gone", {}, INDEX.replace("`solid/a.cpp` | `ns::helper`", "`solid/b.cpp` | "
                                        "`ns::helper`"),
         ["REFERENCES.md:9: Paper99 (3): solid/b.cpp does not exist"]),
        ("tag lost", {"solid/a.cpp": CLEAN["solid/a.cpp"].replace("// [Paper99, Eq. (3)]", "")},
         INDEX, ["REFERENCES.md:9: Paper99 (3): no implementing tag inside ns::helper"]),
        ("gap in the rows", {}, INDEX.replace("| Paper99 (2) | — | derivation only | two |\n",
                                              ""),
         ["REFERENCES.md: Paper99: no rows for equation(s) 2",
          "solid/a.cpp:1: [Paper99, Eq. (2)] names Paper99 (2)",
          "solid/a.cpp:16: [Paper99, Eq. (2)] names Paper99 (2)",
          "solid/a.hpp:1: [Paper99, Eqs. (1)–(3)] names Paper99 (2)"]),
    ]
    failed = 0
    for name, files, index, expected in cases:
        got = run(files, index)
        ok = (not expected and not got) or (
            len(got) == len(expected) and all(any(e in g for g in got) for e in expected))
        if not ok:
            failed += 1
            print(f"self-test '{name}': expected {expected}, got {got}")
    print(f"self-test: {len(cases) - failed} of {len(cases)} cases as expected")
    return 1 if failed else 0


def main(argv):
    if argv[1:] == ["--self-test"]:
        return self_test()
    if len(argv) != 2 or not os.path.isdir(argv[1]):
        print("usage: check_equation_index.py SOURCE_DIR | --self-test", file=sys.stderr)
        return 2
    errors = check(argv[1])
    for e in errors:
        print(e)
    if errors:
        print(f"{len(errors)} violation(s) of the equation index convention (REFERENCES.md, "
              f"'Equation index')")
        return 1
    print("equation index: every tag agrees with REFERENCES.md")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
