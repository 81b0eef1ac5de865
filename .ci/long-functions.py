#!/usr/bin/env python3
"""Lists the functions outside tests that are over 100 lines (from the `fn` line to its closing
brace) and give no reason: a `// long: why` comment among the comment and attribute lines just
above the `fn`. Exits 1 when it lists any.

Test code is left out: items under `#[test]` or `#[cfg(test)]`, and the files of modules
declared `#[cfg(test)] mod name;`. Usage: python3 .ci/long-functions.py [dir...] (default src
and python/src)."""
import os, re, sys

MAX_LINES = 100


def tokens(src):
    """Yields (kind, text, offset) for the code of a Rust file: comments, strings and char
    literals are skipped, so braces inside them do not count."""
    i, n = 0, len(src)
    while i < n:
        c = src[i]
        if src.startswith('//', i):
            j = src.find('\n', i)
            i = n if j < 0 else j
        elif src.startswith('/*', i):
            depth, i = 1, i + 2
            while i < n and depth:
                if src.startswith('/*', i):
                    depth, i = depth + 1, i + 2
                elif src.startswith('*/', i):
                    depth, i = depth - 1, i + 2
                else:
                    i += 1
        elif (m := re.compile(r'b?r(#*)"').match(src, i)) and (i == 0 or not (src[i - 1].isalnum() or src[i - 1] == '_')):
            end = '"' + m.group(1)
            j = src.find(end, m.end())
            i = n if j < 0 else j + len(end)
        elif c == '"' or src.startswith('b"', i) and not (i and (src[i - 1].isalnum() or src[i - 1] == '_')):
            i += 1 if c == '"' else 2
            while i < n and src[i] != '"':
                i += 2 if src[i] == '\\' else 1
            i += 1
        elif c == "'":
            # A char literal ('a', '\n', '\u{..}') or a lifetime ('a).
            m = re.compile(r"'(\\(u\{[0-9a-fA-F]+\}|x[0-9a-fA-F]{2}|.)|[^\\'])'").match(src, i)
            i = m.end() if m else i + 1
        elif c.isalpha() or c == '_':
            m = re.compile(r'\w+').match(src, i)
            yield 'ident', m.group(0), i
            i = m.end()
        elif c.isspace() or c.isdigit():
            i += 1
        else:
            yield 'punct', c, i
            i += 1


def item_end(toks, k):
    """The index of the token that ends the item starting at toks[k]: its first `;` outside
    brackets, or the `}` closing its first top-level `{`."""
    depth = 0
    while k < len(toks):
        t = toks[k][1]
        if t in '([':
            depth += 1
        elif t in ')]':
            depth -= 1
        elif t == ';' and depth == 0:
            return k
        elif t == '{' and depth == 0:
            level = 0
            while k < len(toks):
                if toks[k][1] == '{':
                    level += 1
                elif toks[k][1] == '}':
                    level -= 1
                    if level == 0:
                        return k
                k += 1
        k += 1
    return len(toks) - 1


def scan(path, src, test_files):
    """Returns (line, name, lines) for each long function of one file without a reason, and
    adds the files of `#[cfg(test)] mod name;` to test_files."""
    toks = list(tokens(src))
    line_of = lambda off: src.count('\n', 0, off) + 1
    lines = src.split('\n')
    test_ranges = []  # (start offset, end offset) of items under #[test] / #[cfg(test)]
    found = []
    for k, (kind, text, off) in enumerate(toks):
        if text == '#' and k + 2 < len(toks) and toks[k + 1][1] == '[':
            j = k + 2
            attr = []
            while j < len(toks) and toks[j][1] != ']':
                attr.append(toks[j][1])
                j += 1
            if attr in (['test'], ['cfg', '(', 'test', ')']):
                # The item after this attribute (and any further attributes).
                while j + 1 < len(toks) and toks[j + 1][1] == '#':
                    j = item_end(toks, j + 2) if toks[j + 2][1] == '[' else j + 1
                end = item_end(toks, j + 1)
                test_ranges.append((off, toks[end][2]))
                if j + 2 < len(toks) and toks[j + 1][1] == 'mod' and toks[end][1] == ';':
                    name, d = toks[j + 2][1], os.path.dirname(path)
                    base = os.path.basename(path)
                    own = d if base in ('mod.rs', 'lib.rs', 'main.rs') else os.path.join(d, base[:-3])
                    test_files.add(os.path.join(own, name + '.rs'))
                    test_files.add(os.path.join(own, name, 'mod.rs'))
        if kind == 'ident' and text == 'fn' and k + 1 < len(toks) and toks[k + 1][0] == 'ident':
            end = item_end(toks, k + 1)
            if toks[end][1] != '}' or any(a <= off <= b for a, b in test_ranges):
                continue
            first, last = line_of(off), line_of(toks[end][2])
            if last - first + 1 <= MAX_LINES:
                continue
            # The comment and attribute lines just above the fn (its docs, #[...], // long:).
            above, reason = first - 2, False
            while above >= 0 and re.match(r'\s*(//|#\[|#!\[|\*|/\*)', lines[above]):
                reason |= bool(re.match(r'\s*// long:', lines[above]))
                above -= 1
            if not reason:
                found.append((first, toks[k + 1][1], last - first + 1))
    return found


def main():
    roots = sys.argv[1:] or [r for r in ('src', 'python/src') if os.path.isdir(r)]
    files = sorted(os.path.join(d, f) for r in roots for d, _, fs in os.walk(r) for f in fs if f.endswith('.rs'))
    test_files, results = set(), []
    for p in files:
        results.append((p, scan(p, open(p, encoding='utf-8').read(), test_files)))
    bad = 0
    for p, found in results:
        if p in test_files:
            continue
        for line, name, count in found:
            print(f'{p}:{line}: fn {name} is {count} lines (over {MAX_LINES}); split it, or give the reason in a `// long:` comment above it')
            bad += 1
    if bad:
        print(f'{bad} functions over {MAX_LINES} lines without a reason', file=sys.stderr)
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
