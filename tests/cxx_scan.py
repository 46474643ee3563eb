"""Small lexical scanner for the repository checks (check_equation_index.py, check_layers.py,
check_docs.py), and what the checks share: their self-test runner and command line.

Not a C++ parser: it splits a source file into code, comments and string literals, and finds
the function bodies of a .cpp file (their qualified names and extents) by brace matching. That
is enough for this code base's style (clang-format, Google style; no macros that open braces).
"""

import re

LAYERS = ["core", "mesh", "fluid", "solid", "coupling", "io", "scene", "run", "render", "bench",
          "cli"]


class Source:
    """One file: `code` is the text with comments, string/char literals and preprocessor
    lines blanked (same length and line breaks); `comments` and `strings` are
    (offset, text) pairs of the original text, `includes` (line, quoted, target) triples."""

    def __init__(self, path, text):
        self.path = path
        self.text = text
        self.comments = []
        self.strings = []
        self.includes = []  # (line, quoted, target) of each #include
        self._line_starts = [0] + [m.end() for m in re.finditer("\n", text)]
        self.code = self._blank()

    def line_of(self, offset):
        lo, hi = 0, len(self._line_starts)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if self._line_starts[mid] <= offset:
                lo = mid
            else:
                hi = mid
        return lo + 1

    def _blank(self):
        t = self.text
        out = list(t)
        i, n = 0, len(t)
        at_line_start = True

        def blank(a, b):
            for k in range(a, b):
                if out[k] != "\n":
                    out[k] = " "

        while i < n:
            c = t[i]
            if c == "\n":
                at_line_start = True
                i += 1
                continue
            if c in " \t":
                i += 1
                continue
            if at_line_start and c == "#":  # preprocessor line (with continuations)
                j = i
                while j < n and t[j] != "\n":
                    if t[j] == "\\" and j + 1 < n and t[j + 1] == "\n":
                        j += 2
                        continue
                    j += 1
                m = re.match(r'#\s*include\s*(["<])([^">]*)[">]', t[i:j])
                if m:
                    self.includes.append((self.line_of(i), m.group(1) == '"', m.group(2)))
                blank(i, j)
                i = j
                continue
            at_line_start = False
            if t.startswith("//", i):
                j = t.find("\n", i)
                j = n if j < 0 else j
                self.comments.append((i, t[i:j]))
                blank(i, j)
                i = j
            elif t.startswith("/*", i):
                j = t.find("*/", i + 2)
                j = n if j < 0 else j + 2
                self.comments.append((i, t[i:j]))
                blank(i, j)
                i = j
            elif c == 'R' and t.startswith('R"', i) and (i == 0 or not (t[i - 1].isalnum() or t[i - 1] == "_")):
                m = re.match(r'R"([^(\s]*)\(', t[i:])
                end = t.find(")" + m.group(1) + '"', i) if m else -1
                j = n if end < 0 else end + len(m.group(1)) + 2
                self.strings.append((i, t[i:j]))
                blank(i, j)
                i = j
            elif c == '"' or (c == "'" and not (i > 0 and t[i - 1].isalnum())):
                # (a ' after a digit/letter is a digit separator, e.g. 1'000)
                j = i + 1
                while j < n and t[j] != c and t[j] != "\n":
                    j += 2 if t[j] == "\\" else 1
                j = min(j + 1, n)
                self.strings.append((i, t[i:j]))
                blank(i + 1, j - 1)
                i = j
            else:
                i += 1
        return "".join(out)


_QUALIFIERS = re.compile(
    r"^(\s*(const|noexcept(\s*\([^()]*\))?|override|final|mutable|volatile|&&?|"
    r"->\s*[\w:<>,\s*&]+?))*\s*$")
_DECLARATOR = re.compile(r"((?:[A-Za-z_]\w*\s*(?:<[^<>;{}()]*>)?\s*::\s*)*~?"
                         r"(?:operator\s*(?:\(\)|[^\s(]+)|[A-Za-z_]\w*))\s*$")


# The head of a '{' that opens a member's brace initializer in a constructor's initializer
# list, `Foo::Foo(int a) : m_b(a), m_x`, as opposed to the body after `... : m_x{a} `.
_CTOR_BRACE_INIT = re.compile(r"\)\s*(noexcept\s*)?:[^:;][^;]*\w\s*$")


def _top_level_paren(head):
    """Index of the first '(' at parenthesis depth 0 whose matching ')' is followed only by
    qualifiers or a constructor initializer list (the parameter list), or -1."""
    depth = 0
    for k, ch in enumerate(head):
        if ch == "(":
            if depth == 0:
                close = _matching(head, k)
                if close < 0:
                    return -1
                rest = head[close + 1:]
                if _QUALIFIERS.match(rest) or re.match(r"^\s*(const\s*)?(noexcept\s*)?:[^:]", rest):
                    return k
            depth += 1
        elif ch == ")":
            depth -= 1
    return -1


def _matching(s, k):
    depth = 0
    for j in range(k, len(s)):
        if s[j] == "(":
            depth += 1
        elif s[j] == ")":
            depth -= 1
            if depth == 0:
                return j
    return -1


class Function:
    def __init__(self, name, start, end, line):
        self.name, self.start, self.end, self.line = name, start, end, line

    def contains(self, offset):
        return self.start < offset < self.end


def functions(src):
    """The function bodies of a source file: Function(qualified name, offset of '{', offset of
    the matching '}', line of '{'). Qualified names join the named namespaces (anonymous ones
    omitted), enclosing classes and the declarator, e.g. tetfsi::solid::SolidWorld::step.
    Lambdas and nested blocks belong to the enclosing function."""
    code = src.code
    stack = []  # entries: (kind, name, start); kind in namespace, class, function, other
    found = []
    head_start = 0
    i, n = 0, len(code)
    while i < n:
        ch = code[i]
        if ch == ";":
            if not any(k in ("function", "other") for k, _, _ in stack):
                head_start = i + 1
        elif ch == "{":
            head = code[head_start:i]
            if any(k in ("function", "other") for k, _, _ in stack):
                kind, name = "other", ""  # a block, lambda or initializer inside
            elif _CTOR_BRACE_INIT.search(head):  # `: m_x{a}` of an initializer list: skip it
                i = _matching_brace(code, i) + 1
                continue
            else:
                kind, name = _classify(head)
            stack.append((kind, name, i))
            head_start = i + 1
        elif ch == "}":
            if stack:
                kind, name, start = stack.pop()
                if kind == "function":
                    scope = [nm for k, nm, _ in stack if k in ("namespace", "class") and nm]
                    found.append(Function("::".join(scope + [name]), start, i, src.line_of(start)))
            head_start = i + 1
        i += 1
    return found


def _matching_brace(code, k):
    depth = 0
    for j in range(k, len(code)):
        if code[j] == "{":
            depth += 1
        elif code[j] == "}":
            depth -= 1
            if depth == 0:
                return j
    return len(code) - 1


def _classify(head):
    h = " ".join(head.split())
    m = re.match(r"^(inline\s+)?namespace\s*([\w:]*)\s*$", h)
    if m:
        return "namespace", m.group(2)
    if re.match(r'^extern\s*"C"\s*$', h) or re.match(r"^extern\s*$", h):
        return "namespace", ""
    if re.match(r"^(template\s*<.*>\s*)?(enum)\b", h):
        return "other", ""
    m = re.match(r"^(template\s*<.*>\s*)?(class|struct|union)\s+(?:\[\[[^\]]*\]\]\s*)?(\w+)"
                 r"(\s+final)?\s*(:[^(){}]*)?$", h)
    if m:
        return "class", m.group(3)
    k = _top_level_paren(h)
    if k < 0:
        return "other", ""
    before = h[:k]
    if "=" in re.sub(r"operator\s*\S+", "", before):
        return "other", ""
    m = _DECLARATOR.search(before)
    if not m:
        return "other", ""
    name = re.sub(r"\s+", "", m.group(1))
    name = re.sub(r"<[^<>]*>", "", name)  # explicit template arguments of a qualifier
    if name in ("if", "for", "while", "switch", "catch", "return", "sizeof", "decltype"):
        return "other", ""
    return "function", name


def read(path):
    with open(path, encoding="utf-8") as f:
        return Source(path, f.read())


# ---- what the repository checks share -----------------------------------------------------

def self_test_trees(cases, check):
    """Run `check(root)` on made-up trees: `cases` are (name, {relative path: text}, expected
    line prefixes). Prints each case that did not give its expected lines; returns the exit
    code (1 if any failed)."""
    import os
    import tempfile
    failed = 0
    for name, files, expected in cases:
        with tempfile.TemporaryDirectory() as d:
            for rel, text in files.items():
                os.makedirs(os.path.dirname(os.path.join(d, rel)) or d, exist_ok=True)
                with open(os.path.join(d, rel), "w", encoding="utf-8") as f:
                    f.write(text)
            got = check(d)
        ok = len(got) == len(expected) and all(g.startswith(e) for g, e in zip(got, expected))
        if not ok:
            failed += 1
            print(f"self-test '{name}': expected {expected}, got {got}")
    print(f"self-test: {len(cases) - failed} of {len(cases)} cases as expected")
    return 1 if failed else 0


def check_main(argv, script, check, self_test, ok_line, failed_line):
    """The command line every check shares: SOURCE_DIR, or --self-test."""
    import os
    import sys
    if argv[1:] == ["--self-test"]:
        return self_test()
    if len(argv) != 2 or not os.path.isdir(argv[1]):
        print(f"usage: {script} SOURCE_DIR | --self-test", file=sys.stderr)
        return 2
    errors = check(argv[1])
    for e in errors:
        print(e)
    if errors:
        print(failed_line.format(n=len(errors)))
        return 1
    print(ok_line)
    return 0
