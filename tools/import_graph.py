"""The package's import graph: modules, import edges (any import of a pr2_drake module, also
inside functions) and cycles (strongly connected groups of more than one module).

    python tools/import_graph.py [ROOT]
"""

import ast
import sys
from pathlib import Path


def graph(root: Path) -> dict[str, set[str]]:
    pkg = root / "pr2_drake"
    mods = {}
    for path in pkg.rglob("*.py"):
        rel = path.relative_to(root).with_suffix("")
        name = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
        mods[name] = path
    edges: dict[str, set[str]] = {m: set() for m in mods}
    for name, path in mods.items():
        for node in ast.walk(ast.parse(path.read_text())):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            for t in targets:
                if t in mods and t != name:
                    edges[name].add(t)
    return edges


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))

    sys.setrecursionlimit(10000)
    for v in edges:
        if v not in index:
            visit(v)
    return out


def main(root: str = ".") -> int:
    edges = graph(Path(root))
    n_edges = sum(len(v) for v in edges.values())
    cyc = cycles(edges)
    print(f"modules {len(edges)}, import edges {n_edges}, cycles {len(cyc)}")
    for c in cyc:
        print("  cycle:", " <-> ".join(c))
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
