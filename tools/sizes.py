"""House-rule sizes: modules of pr2_drake/ over 600 lines, functions over 100 lines.

    python tools/sizes.py [ROOT]      (exit status 1 if any)
"""

import ast
import sys
from pathlib import Path

MAX_MODULE, MAX_FUNCTION = 600, 100


def main(root: str = ".") -> int:
    bad = 0
    for path in sorted(Path(root, "pr2_drake").rglob("*.py")):
        text = path.read_text()
        n = len(text.splitlines())
        rel = path.relative_to(root)
        if n > MAX_MODULE:
            print(f"module   {rel}: {n} lines")
            bad += 1
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION:
                    print(f"function {rel}:{node.lineno} {node.name}: {length} lines")
                    bad += 1
    print(f"{bad} over the limits (modules > {MAX_MODULE} lines, functions > {MAX_FUNCTION})")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
