"""``pr2-drake leaderboard DIR``: rank the submissions of a ``compete`` results folder.

Per submission and task: the mean score over the seeds and the mean completion time (the
simulated time of the episodes that earned full marks). Rank by total mean score, ties by the
total completion time (tasks never completed count as the task's time limit). Writes
``DIR/leaderboard.md`` and ``DIR/leaderboard.html`` and, with matplotlib (``pip install
'pr2-drake[compete]'``), the figures of the paper in ``DIR/plots``:

- ``score_distribution.png``: per task, the share of episodes at each score (full marks
  marked), as the paper's "Performance statistics";
- ``completion_times.png``: box plots of the completion time (simulated time at the end of
  the episode) by score, per task;
- ``category_points.png``: average points in locomotion (tasks 1, 3, 4, 5), manipulation
  (2, 6) and perception (6) against the points available.
"""

from __future__ import annotations

import html
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

CATEGORIES = {"locomotion": (1, 3, 4, 5), "manipulation": (2, 6), "perception": (6,)}
INSTALL_HINT = "pip install 'pr2-drake[compete]'  (matplotlib)"


def load_rows(folder: str | Path) -> list[dict[str, Any]]:
    """The episodes of a results folder (results.json, else episodes.jsonl)."""
    folder = Path(folder)
    if (folder / "results.json").is_file():
        return json.loads((folder / "results.json").read_text())["episodes"]
    if (folder / "episodes.jsonl").is_file():
        from pr2_drake.compete.runner import read_done

        return list(read_done(folder / "episodes.jsonl").values())
    raise ValueError(f"{folder}: no results.json or episodes.jsonl (run pr2-drake compete)")


def standings(rows: list[dict[str, Any]]) -> tuple[list[int], list[dict[str, Any]]]:
    """(tasks, one entry per submission, ranked): {submission, total, time, tasks: {task:
    {score, max_score, time, episodes}}}."""
    from pr2_drake.tasks import get_task

    tasks = sorted({int(r["task"]) for r in rows})
    by = defaultdict(list)
    for r in rows:
        by[(r["submission"], int(r["task"]))].append(r)
    limits = {t: float(get_task(t).spec.time_limit) for t in tasks}
    table = []
    for sub in sorted({r["submission"] for r in rows}):
        entry = {"submission": sub, "tasks": {}, "total": 0.0, "time": 0.0}
        for t in tasks:
            eps = by.get((sub, t), [])
            if not eps:
                entry["tasks"][t] = {"score": 0.0, "max_score": None, "time": None,
                                     "episodes": 0}
                entry["time"] += limits[t]
                continue
            score = sum(e["score"] for e in eps) / len(eps)
            full = [e["sim_time"] for e in eps if e["score"] >= e["max_score"]]
            tm = sum(full) / len(full) if full else None
            entry["tasks"][t] = {"score": score, "max_score": eps[0]["max_score"], "time": tm,
                                 "episodes": len(eps)}
            entry["total"] += score
            entry["time"] += tm if tm is not None else limits[t]
        table.append(entry)
    table.sort(key=lambda e: (-e["total"], e["time"], e["submission"]))
    return tasks, table


def markdown(tasks: list[int], table: list[dict[str, Any]]) -> str:
    head = "| rank | submission | total | " + " | ".join(f"task {t}" for t in tasks) + " |"
    rule = "|---:|---|---:|" + "---:|" * len(tasks)
    lines = ["# Leaderboard", "",
             "Mean score over the seeds per task (mean completion time of full-mark episodes, "
             "simulated s). Rank by total score, ties by total completion time.", "", head, rule]
    for i, e in enumerate(table, 1):
        cells = []
        for t in tasks:
            c = e["tasks"][t]
            time = f" ({c['time']:.1f} s)" if c["time"] is not None else ""
            cells.append(f"{c['score']:.1f}{time}" if c["episodes"] else "-")
        lines.append(f"| {i} | {e['submission']} | {e['total']:.1f} | " + " | ".join(cells)
                     + " |")
    return "\n".join(lines) + "\n"


def html_page(tasks: list[int], table: list[dict[str, Any]], plots: list[str]) -> str:
    rows = []
    for i, e in enumerate(table, 1):
        cells = "".join(
            f"<td>{c['score']:.1f}" + (f" <small>({c['time']:.1f} s)</small>"
                                       if c["time"] is not None else "") + "</td>"
            if c["episodes"] else "<td>-</td>" for c in (e["tasks"][t] for t in tasks))
        rows.append(f"<tr><td>{i}</td><td>{html.escape(e['submission'])}</td>"
                    f"<td><b>{e['total']:.1f}</b></td>{cells}</tr>")
    head = "".join(f"<th>task {t}</th>" for t in tasks)
    images = "".join(f'<p><img src="{p}" style="max-width:100%"></p>' for p in plots)
    return ("<!doctype html><html><head><meta charset='utf-8'><title>Leaderboard</title>"
            "<style>body{font-family:sans-serif} td,th{padding:4px 10px;text-align:right}"
            "</style></head><body><h1>Leaderboard</h1><p>Mean score over the seeds per task "
            "(mean completion time of full-mark episodes, simulated s). Rank by total score, "
            "ties by total completion time.</p><table><tr><th>rank</th><th>submission</th>"
            f"<th>total</th>{head}</tr>{''.join(rows)}</table>{images}</body></html>\n")


def write_plots(rows: list[dict[str, Any]], tasks: list[int], table, folder: Path) -> list[str]:
    """The three figures (see the module docstring); returns their paths relative to
    ``folder``. Raises ImportError without matplotlib."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pr2_drake.tasks import get_task

    out = folder / "plots"
    out.mkdir(exist_ok=True)
    n = len(tasks)
    fig, axes = plt.subplots(1, n, figsize=(3.2 * n, 3.0), squeeze=False)
    for ax, t in zip(axes[0], tasks):
        scores = [r["score"] for r in rows if int(r["task"]) == t]
        top = float(get_task(t).spec.max_score)
        values = sorted(set(scores) | {0.0, top})
        shares = [100.0 * scores.count(v) / max(1, len(scores)) for v in values]
        bars = ax.bar([f"{v:g}" for v in values], shares, color="tab:blue")
        bars[values.index(top)].set_color("tab:green")
        ax.set_title(f"task {t}")
        ax.set_xlabel("score (green: full marks)")
        ax.set_ylim(0, 100)
    axes[0][0].set_ylabel("share of episodes [%]")
    fig.tight_layout()
    fig.savefig(out / "score_distribution.png", dpi=100)
    plt.close(fig)

    fig, axes = plt.subplots(1, n, figsize=(3.2 * n, 3.0), squeeze=False)
    for ax, t in zip(axes[0], tasks):
        groups = defaultdict(list)
        for r in rows:
            if int(r["task"]) == t:
                groups[r["score"]].append(r["sim_time"])
        keys = sorted(groups)
        if keys:
            ax.boxplot([groups[k] for k in keys])
            ax.set_xticks(range(1, len(keys) + 1), [f"{k:g}" for k in keys])
        ax.set_title(f"task {t}")
        ax.set_xlabel("score")
    axes[0][0].set_ylabel("completion time [s, simulated]")
    fig.tight_layout()
    fig.savefig(out / "completion_times.png", dpi=100)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5, 3))
    names, got, avail = [], [], []
    for cat, cat_tasks in CATEGORIES.items():
        present = [t for t in cat_tasks if t in tasks]
        if not present:
            continue
        names.append(cat)
        avail.append(sum(float(get_task(t).spec.max_score) for t in present))
        got.append(sum(sum(e["tasks"][t]["score"] for e in table) / max(1, len(table))
                       for t in present))
    x = range(len(names))
    ax.bar([i - 0.2 for i in x], avail, 0.4, label="available", color="lightgray")
    ax.bar([i + 0.2 for i in x], got, 0.4, label="average earned", color="tab:blue")
    ax.set_xticks(list(x), names)
    ax.set_ylabel("points")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "category_points.png", dpi=100)
    plt.close(fig)
    return [f"plots/{p}" for p in ("score_distribution.png", "completion_times.png",
                                   "category_points.png")]


def write_leaderboard(folder: str | Path, plots: bool = True) -> str:
    """Write leaderboard.md, leaderboard.html (and the plots); returns the table as text."""
    folder = Path(folder)
    rows = load_rows(folder)
    tasks, table = standings(rows)
    text = markdown(tasks, table)
    images: list[str] = []
    note = ""
    if plots:
        try:
            images = write_plots(rows, tasks, table, folder)
            note = f"plots in {folder / 'plots'}"
        except ImportError:
            note = f"no plots: matplotlib is not installed ({INSTALL_HINT})"
    (folder / "leaderboard.md").write_text(text)
    (folder / "leaderboard.html").write_text(html_page(tasks, table, images))
    return text + f"\nwritten: {folder / 'leaderboard.md'}, {folder / 'leaderboard.html'}" + (
        f"; {note}" if note else "")
