#!/usr/bin/env python3
"""Print the longest functions of C++ files: lines from the signature's first line to the
closing brace (lambdas count inside their function).

usage: scripts/function_lengths.py [--max N] FILE...   (exit 1 if a function exceeds N)
"""
import re
import sys


def strip(src):
    """Blank out comments and string/char literals, keeping line breaks."""
    out, i, n = [], 0, len(src)
    while i < n:
        c = src[i]
        if src.startswith('//', i):
            j = src.find('\n', i)
            j = n if j < 0 else j
            out.append(' ' * (j - i)); i = j
        elif src.startswith('/*', i):
            j = src.find('*/', i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r'[^\n]', ' ', src[i:j])); i = j
        elif c == 'R' and src.startswith('R"', i):
            m = re.match(r'R"([^(]*)\(', src[i:])
            end = src.find(')' + m.group(1) + '"', i)
            end = n if end < 0 else end + len(m.group(1)) + 2
            out.append(re.sub(r'[^\n]', ' ', src[i:end])); i = end
        elif c in '"\'':
            j = i + 1
            while j < n and src[j] != c:
                j += 2 if src[j] == '\\' else 1
            out.append(c + ' ' * (j - i - 1) + c); i = j + 1
        else:
            out.append(c); i += 1
    return ''.join(out)


CONTROL = re.compile(r'\b(if|for|while|switch|catch|do|else|try)\s*(\(|$)')
SCOPE = re.compile(r'\b(namespace|class|struct|union|enum)\b')


def functions(path):
    src = strip(open(path, encoding='utf-8').read())
    stack = []  # (kind, start_line)
    head_start = 0  # index where the current statement head began
    line = 1
    res = []
    for i, c in enumerate(src):
        if c == '\n':
            line += 1
        if c == '{':
            head = src[head_start:i]
            in_func = any(k == 'func' for k, _ in stack)
            kind = 'block'
            if not in_func:
                if SCOPE.search(head) and ')' not in head.split('{')[-1]:
                    kind = 'scope'
                elif ')' in head and not CONTROL.search(head.strip()):
                    kind = 'func'
            first = line - head.strip('\n').count('\n') if kind == 'func' else line
            # the signature's first line: skip leading blank lines of the head
            lead = len(head) - len(head.lstrip())
            first = line - head[lead:].count('\n')
            stack.append((kind, first))
            head_start = i + 1
        elif c == '}':
            if stack:
                kind, first = stack.pop()
                if kind == 'func':
                    name = re.sub(r'\s+', ' ', src[:0] or '')
                    res.append((line - first + 1, first))
            head_start = i + 1
        elif c == ';':
            head_start = i + 1
    return res


def main(argv):
    limit = None
    if len(argv) > 1 and argv[0] == '--max':
        limit = int(argv[1]); argv = argv[2:]
    worst = []
    for p in argv:
        for n, first in functions(p):
            worst.append((n, f'{p}:{first}'))
    worst.sort(reverse=True)
    for n, where in worst[:10]:
        print(f'{n:5d}  {where}')
    if limit is not None and worst and worst[0][0] > limit:
        print(f'longest function is {worst[0][0]} lines (> {limit})')
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
