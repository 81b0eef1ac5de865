#!/usr/bin/env python3
"""Lists the circles of imports between the modules of a Rust source tree: every strongly
connected set of modules (two or more that import one another through `crate::` and
`super::` paths, however long the way round; comments stripped, a child's use of its own
parent does not count), each with one circle through all of it, shortest first.

Usage: python3 .ci/module-cycles.py [SRC ...] [--fail]. With --fail it exits 1 when any
tree has a circle: CI runs it so on the crates that must have none (crates/core/src,
crates/data/src). Over the root crate (src/) it is a review aid: the circles it lists are
the layering work left (docs/extending.md)."""
import os, re, sys
from collections import deque


def modules(root):
    mods = {}
    for d, _, fs in os.walk(root):
        for f in fs:
            if not f.endswith('.rs'):
                continue
            p = os.path.join(d, f)
            rel = os.path.relpath(p, root)[:-3].split(os.sep)
            if rel[-1] in ('mod', 'lib', 'main'):
                rel = rel[:-1]
            mods[tuple(rel)] = p
    return mods


def edges_of(mods):
    def resolve(path):
        path = tuple(path)
        while path and path not in mods:
            path = path[:-1]
        return path if path else None

    edges = {m: set() for m in mods}

    def add(m, t):
        if t and t != m and m[:len(t)] != t:
            edges[m].add(t)

    for m, p in mods.items():
        src = re.sub(r'//[^\n]*', '', open(p).read())
        for mm in re.finditer(r'crate::((?:\w+::)*\w+)', src):
            add(m, resolve(mm.group(1).split('::')))
        for mm in re.finditer(r'use crate::\{([^;]*)\};', src, re.S):
            for part in mm.group(1).split(','):
                part = part.strip().split('{')[0].strip(':')
                if part:
                    add(m, resolve(part.split('::')))
        for mm in re.finditer(r'\b((?:super::)+)((?:\w+::)*\w+)', src):
            up = mm.group(1).count('super::')
            add(m, resolve(list(m[:len(m) - up]) + mm.group(2).split('::')))
    return edges


def components(edges):
    """Tarjan's strongly connected components with two or more modules."""
    index, low, on, stack, out, n = {}, {}, set(), [], [], [0]
    sys.setrecursionlimit(10000)

    def visit(v):
        index[v] = low[v] = n[0]
        n[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def shortest_circle(edges, comp):
    """The shortest circle through the component's first module (breadth first)."""
    inside, start = set(comp), comp[0]
    prev, queue = {start: None}, deque([start])
    while queue:
        v = queue.popleft()
        for w in sorted(edges[v] & inside):
            if w == start:
                path = [v]
                while prev[path[-1]] is not None:
                    path.append(prev[path[-1]])
                return list(reversed(path)) + [start]
            if w not in prev:
                prev[w] = v
                queue.append(w)
    return comp


def main():
    args = [a for a in sys.argv[1:] if a != '--fail']
    fail = '--fail' in sys.argv[1:]
    found = 0
    for root in args or ['src']:
        edges = edges_of(modules(root))
        comps = sorted(components(edges), key=len)
        for comp in comps:
            circle = shortest_circle(edges, comp)
            print(f'{root}: {len(comp)} modules: ' + ' -> '.join('::'.join(m) for m in circle))
        print(f'{root}: {len(comps)} circles of imports', file=sys.stderr)
        found += len(comps)
    sys.exit(1 if fail and found else 0)


if __name__ == '__main__':
    main()
