"""Compare two sets of episode reports field by field, wall-clock fields aside.

    python tools/same_reports.py OLD.json NEW.json [OLD2.json NEW2.json ...]

Each file is what ``pr2-drake eval --out`` writes (``{"summary": ..., "episodes": [...]}``) or
a list of reports (tools/fingerprint.py). Prints every difference; exit status 1 if any.
"""

import json
import sys

WALL_CLOCK = {"wall_time", "real_time_factor", "mean_real_time_factor", "wall_time_mean",
              "mean_wall_time", "total_wall_time"}


def strip(x):
    if isinstance(x, dict):
        return {k: strip(v) for k, v in x.items() if k not in WALL_CLOCK}
    if isinstance(x, list):
        return [strip(v) for v in x]
    return x


def diff(a, b, where="") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b), key=str):
            if k not in a or k not in b:
                out.append(f"{where}.{k}: only in {'new' if k not in a else 'old'}")
            else:
                out += diff(a[k], b[k], f"{where}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} entries vs {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in diff(x, y, f"{where}[{i}]")]
    return [] if a == b and type(a) is type(b) else [f"{where}: {a!r} != {b!r}"]


def main(argv: list[str]) -> int:
    if len(argv) < 2 or len(argv) % 2:
        print(__doc__)
        return 2
    bad = 0
    for old, new in zip(argv[::2], argv[1::2]):
        d = diff(strip(json.load(open(old))), strip(json.load(open(new))))
        print(f"{old} vs {new}: {'IDENTICAL' if not d else f'{len(d)} differences'}")
        for line in d[:40]:
            print("   ", line)
        bad += bool(d)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
