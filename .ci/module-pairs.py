#!/usr/bin/env python3
"""Lists pairs of modules under src/ that import each other through `crate::` and `super::`
paths (comments stripped; a child's use of its own parent does not count).

Usage: python3 .ci/module-pairs.py [src]. A review aid, not run by CI: the pairs it still
lists (gpu::backend with the hand-dispatched ferns, keypoints, candidates and loops) are
named in docs/extending.md."""
import os, re, sys
root = sys.argv[1] if len(sys.argv) > 1 else 'src'
mods = {}
for d, _, fs in os.walk(root):
    for f in fs:
        if not f.endswith('.rs'): continue
        p = os.path.join(d, f)
        rel = os.path.relpath(p, root)[:-3].split(os.sep)
        if rel[-1] in ('mod', 'lib', 'main'): rel = rel[:-1]
        mods[tuple(rel)] = p
def resolve(path):
    path = tuple(path)
    while path and path not in mods: path = path[:-1]
    return path if path else None
edges = set()
for m, p in mods.items():
    src = open(p).read()
    src = re.sub(r'//[^\n]*', '', src)
    # crate:: paths, including grouped use crate::{a::b, c}
    for mm in re.finditer(r'crate::((?:\w+::)*\w+)', src):
        t = resolve(mm.group(1).split('::'))
        if t and t != m and not (m[:len(t)] == t): edges.add((m, t))
    for mm in re.finditer(r'use crate::\{([^;]*)\};', src, re.S):
        for part in re.split(r',', mm.group(1)):
            part = part.strip().split('{')[0].strip(':')
            if part:
                t = resolve(part.split('::'))
                if t and t != m and not (m[:len(t)] == t): edges.add((m, t))
    for mm in re.finditer(r'\b((?:super::)+)((?:\w+::)*\w+)', src):
        up = mm.group(1).count('super::')
        b = m[:len(m) - up]
        t = resolve(list(b) + mm.group(2).split('::'))
        if t and t != m and not (m[:len(t)] == t): edges.add((m, t))
pairs = sorted({tuple(sorted((a, b))) for a, b in edges if (b, a) in edges})
for a, b in pairs:
    print('::'.join(a), '<->', '::'.join(b))
print(f'{len(pairs)} pairs of modules import each other', file=sys.stderr)
