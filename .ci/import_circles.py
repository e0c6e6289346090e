#!/usr/bin/env python3
"""Import circles between source files of each crate: an edge a -> b when file a names an item
through a path that resolves to file b (use statements and inline crate::/super:: paths).
A parent's `mod x;` and `pub use x::...` re-exports of its own children are not edges."""
import os, re, sys
from collections import defaultdict

def files(src):
    out = {}
    for root, _, fs in os.walk(src):
        for f in fs:
            if f.endswith('.rs') and '/bin' not in root:
                p = os.path.join(root, f)
                rel = os.path.relpath(p, src)[:-3]
                parts = rel.split(os.sep)
                if parts[-1] in ('mod', 'lib'):
                    parts = parts[:-1]
                out[tuple(parts)] = p
    return out

def resolve(mods, path):
    # longest prefix of path that is a module file
    for k in range(len(path), -1, -1):
        if tuple(path[:k]) in mods:
            return tuple(path[:k])
    return None

def analyse(src):
    mods = files(src)
    edges = defaultdict(set)
    for m, p in mods.items():
        text = open(p).read()
        text = re.sub(r'#\[cfg\(test\)\]\s*mod tests\s*\{.*', '', text, flags=re.S)
        text = re.sub(r'//.*', '', text)
        is_dir = os.path.basename(p) in ('mod.rs', 'lib.rs')
        here = list(m)  # relative paths name child modules (siblings need `super::`)
        # expand `use a::{b, c::d}` roughly: take the prefix before '{'
        for stmt in re.findall(r'(?:pub(?:\([^)]*\))?\s+)?use\s+([^;]+);', text):
            pass
        for full in re.finditer(r'(pub(?:\([^)]*\))?\s+)?use\s+([^;]+);', text):
            public, path = full.group(1), full.group(2).replace(' ', '').replace('\n', '')
            prefixes = []
            if '{' in path:
                base, inner = path.split('{', 1)
                inner = inner.rsplit('}', 1)[0]
                for item in re.split(r',(?![^{]*\})', inner):
                    prefixes.append(base + item.split('{')[0])
            else:
                prefixes.append(path)
            for pre in prefixes:
                segs = [s for s in pre.split('::') if s]
                if not segs:
                    continue
                if segs[0] == 'crate':
                    target = segs[1:]
                elif segs[0] == 'super':
                    base = list(m[:-1]) if not is_dir else list(m[:-1])
                    n = 0
                    while segs and segs[0] == 'super':
                        segs = segs[1:]; n += 1
                    base = list(m)[:len(m) - n] if is_dir else list(m)[:len(m) - n]
                    target = base + segs
                elif segs[0] == 'self' or tuple(here + [segs[0]]) in mods:
                    if segs[0] == 'self':
                        segs = segs[1:]
                    if public and is_dir:
                        continue  # a facade re-exporting its own children
                    target = here + segs
                else:
                    continue
                t = resolve(mods, target)
                if t is not None and t != m:
                    edges[m].add(t)
        for mt in re.finditer(r'\b(crate|super)::([A-Za-z_][\w:]*)', text):
            segs = [mt.group(1)] + mt.group(2).split('::')
            if segs[0] == 'crate':
                target = segs[1:]
            else:
                n = 0
                while segs and segs[0] == 'super':
                    segs = segs[1:]; n += 1
                target = list(m)[:len(m) - n] + segs
            t = resolve(mods, target)
            if t is not None and t != m:
                edges[m].add(t)
    # strongly connected components (Tarjan)
    index, low, stack, on, out, i = {}, {}, [], set(), [], [0]
    def strong(v):
        index[v] = low[v] = i[0]; i[0] += 1; stack.append(v); on.add(v)
        for w in edges[v]:
            if w not in index:
                strong(w); low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop(); on.discard(w); comp.append(w)
                if w == v: break
            if len(comp) > 1:
                out.append(comp)
    sys.setrecursionlimit(10000)
    for v in list(mods):
        if v not in index:
            strong(v)
    return out

bad = False
for crate in sys.argv[1:]:
    for comp in analyse(os.path.join(crate, 'src')):
        bad = True
        print(crate, 'circle:', ' <-> '.join('/'.join(c) or 'lib' for c in comp))
print("import circles found" if bad else "no import circles")
sys.exit(1 if bad else 0)
