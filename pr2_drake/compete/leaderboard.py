"""``pr2-drake leaderboard DIR``: rank the submissions of a ``compete`` results folder.

Per submission and task: the mean score over the seeds and the mean completion time (the
simulated time of the episodes that earned full marks); the scenario switches the episodes ran
with (``scene.variation``: scenes drawn from the seeds, ``randomize``: randomised physics;
``none``: the tasks as given) in a column of their own. Rank by total mean score, ties by the
total completion time (tasks never completed count as the task's time limit). Writes
``DIR/leaderboard.md`` and ``DIR/leaderboard.html`` and, with matplotlib (``pip install
'pr2-drake[compete]'``), the figures of the paper in ``DIR/plots``:

- ``score_distribution.png``: per task, the share of episodes at each score (full marks
  green, and outlined even when no episode earned them), as the paper's "Performance
  statistics";
- ``completion_times.png``: box plots of the completion time (simulated time at the end of
  the episode) by score, per task, every episode a dot, the task's time limit dashed;
- ``category_points.png``: average points in locomotion (tasks 1, 3, 4, 5), manipulation
  (2, 6) and perception (6) against the points available (mean over the submissions).

Panels are laid out three a row.
"""

from __future__ import annotations

import html
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

from pr2_drake.compete import ledger

CATEGORIES = {"locomotion": (1, 3, 4, 5), "manipulation": (2, 6), "perception": (6,)}
INSTALL_HINT = "pip install 'pr2-drake[compete]'  (matplotlib)"


def load_rows(folder: str | Path) -> list[dict[str, Any]]:
    """The episodes of a results folder (results.json, else the rows of episodes.jsonl whose
    MAC checks)."""
    folder = Path(folder)
    if (folder / "results.json").is_file():
        return json.loads((folder / "results.json").read_text())["episodes"]
    if (folder / "episodes.jsonl").is_file() and (folder / ledger.KEY_FILE).is_file():
        return list(ledger.read_rows(folder / "episodes.jsonl",
                                     ledger.run_key(folder))[0].values())
    raise ValueError(f"{folder}: no results.json or episodes.jsonl (run pr2-drake compete)")


def standings(rows: list[dict[str, Any]]) -> tuple[list[int], list[dict[str, Any]]]:
    """(tasks, one entry per submission, ranked): {submission, scenario, total, time, tasks:
    {task: {score, max_score, time, episodes}}}; ``scenario`` names the switches its episodes
    ran with (:func:`scenario_label`)."""
    from pr2_drake.tasks import get_task

    tasks = sorted({int(r["task"]) for r in rows})
    by = defaultdict(list)
    for r in rows:
        by[(r["submission"], int(r["task"]))].append(r)
    limits = {t: float(get_task(t).spec.time_limit) for t in tasks}
    table = []
    for sub in sorted({r["submission"] for r in rows}):
        entry = {"submission": sub, "tasks": {}, "total": 0.0, "time": 0.0,
                 "scenario": scenario_label(r for r in rows if r["submission"] == sub)}
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


def scenario_label(rows) -> str:
    """The scenario switches of these rows (``scenario`` in each), ``+``-joined; ``none`` when
    off; every set seen, ``, ``-joined, when they differ."""
    seen = sorted({"+".join(r.get("scenario", [])) or "none" for r in rows})
    return ", ".join(seen) or "none"


def markdown(tasks: list[int], table: list[dict[str, Any]]) -> str:
    head = ("| rank | submission | scenario | total | " + " | ".join(f"task {t}" for t in tasks)
            + " |")
    rule = "|---:|---|---|---:|" + "---:|" * len(tasks)
    lines = ["# Leaderboard", "",
             "Mean score over the seeds per task (mean completion time of full-mark episodes, "
             "simulated s). Rank by total score, ties by total completion time. Scenario: the "
             "switches the episodes ran with (scene.variation, randomize; none: the tasks as "
             "given).", "", head, rule]
    for i, e in enumerate(table, 1):
        cells = []
        for t in tasks:
            c = e["tasks"][t]
            time = f" ({c['time']:.1f} s)" if c["time"] is not None else ""
            cells.append(f"{c['score']:.1f}{time}" if c["episodes"] else "-")
        lines.append(f"| {i} | {e['submission']} | {e['scenario']} | {e['total']:.1f} | "
                     + " | ".join(cells)
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
                    f"<td>{html.escape(e['scenario'])}</td>"
                    f"<td><b>{e['total']:.1f}</b></td>{cells}</tr>")
    head = "".join(f"<th>task {t}</th>" for t in tasks)
    images = "".join(f'<p><img src="{p}" style="max-width:100%"></p>' for p in plots)
    return ("<!doctype html><html><head><meta charset='utf-8'><title>Leaderboard</title>"
            "<style>body{font-family:sans-serif} td,th{padding:4px 10px;text-align:right}"
            "</style></head><body><h1>Leaderboard</h1><p>Mean score over the seeds per task "
            "(mean completion time of full-mark episodes, simulated s). Rank by total score, "
            "ties by total completion time. Scenario: the switches the episodes ran with "
            "(scene.variation, randomize; none: the tasks as given).</p><table><tr>"
            f"<th>rank</th><th>submission</th><th>scenario</th><th>total</th>{head}</tr>{''.join(rows)}</table>{images}</body></html>\n")


def _grid(plt, n: int):
    """A figure of ``n`` panels, at most three a row; returns (fig, the n axes)."""
    cols = min(3, n)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.3 * rows), squeeze=False)
    flat = list(axes.flat)
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


PLOTS = ("score_distribution.png", "completion_times.png", "category_points.png")


def write_plots(rows: list[dict[str, Any]], tasks: list[int], table, folder: Path) -> list[str]:
    """The three figures (see the module docstring); returns their paths relative to
    ``folder``. Raises ImportError without matplotlib."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pr2_drake.tasks import get_task

    out = folder / "plots"
    out.mkdir(exist_ok=True)
    specs = {t: get_task(t).spec for t in tasks}
    for name, draw in zip(PLOTS, (_score_distribution, _completion_times, _category_points)):
        fig = draw(plt, rows, tasks, specs, table)
        fig.tight_layout()
        fig.savefig(out / name, dpi=100)
        plt.close(fig)
    return [f"plots/{p}" for p in PLOTS]


def _score_distribution(plt, rows, tasks, specs, table):
    """Per task: the share of episodes at each score, full marks marked."""
    fig, axes = _grid(plt, len(tasks))
    for ax, t in zip(axes, tasks):
        scores = [r["score"] for r in rows if int(r["task"]) == t]
        top = float(specs[t].max_score)
        values = sorted(set(scores) | {0.0, top})
        shares = [100.0 * scores.count(v) / max(1, len(scores)) for v in values]
        x = range(len(values))
        colors = ["tab:green" if v == top else "tab:blue" for v in values]
        bars = ax.bar(x, shares, color=colors)
        # Full marks stay marked when nobody earned them: an outlined slot and its label.
        i_top = values.index(top)
        ax.bar([i_top], [100.0], fill=False, edgecolor="tab:green", linestyle="--",
               linewidth=1.0)
        ax.text(i_top, 119.0, "full marks", ha="center", va="top", fontsize=8,
                color="tab:green")
        for b, share in zip(bars, shares):
            if share > 0:
                ax.text(b.get_x() + b.get_width() / 2, share + 1.5, f"{share:.0f}%",
                        ha="center", va="bottom", fontsize=8)
        ax.set_xticks(list(x), [f"{v:g}" for v in values])
        ax.set_title(f"task {t} {specs[t].name} ({len(scores)} episodes)", fontsize=10)
        ax.set_xlabel("score")
        ax.set_ylabel("share of episodes [%]")
        ax.set_ylim(0, 120)  # room above 100 % for the labels
        ax.set_yticks(range(0, 101, 20))
    return fig


def _completion_times(plt, rows, tasks, specs, table):
    """Per task and score: the simulated completion times, the time limit marked."""
    fig, axes = _grid(plt, len(tasks))
    for ax, t in zip(axes, tasks):
        groups = defaultdict(list)
        for r in rows:
            if int(r["task"]) == t:
                groups[r["score"]].append(r["sim_time"])
        keys = sorted(groups)
        top = float(specs[t].max_score)
        limit = float(specs[t].time_limit)
        if keys:
            box = ax.boxplot([groups[k] for k in keys], patch_artist=True, widths=0.5,
                             medianprops={"color": "black"}, showfliers=False)
            for patch, k in zip(box["boxes"], keys):
                patch.set_facecolor("palegreen" if k >= top else "lightsteelblue")
            for i, k in enumerate(keys, 1):  # every episode a dot: flat boxes hide them
                ax.plot([i] * len(groups[k]), groups[k], "o", markersize=4, alpha=0.7,
                        color="tab:green" if k >= top else "tab:blue", zorder=3)
            ax.set_xticks(range(1, len(keys) + 1),
                          [f"{k:g}\n(n={len(groups[k])})" for k in keys])
        ax.axhline(limit, color="tab:red", linestyle="--", linewidth=1.0)
        ax.text(0.02, limit, "time limit", transform=ax.get_yaxis_transform(), fontsize=8,
                color="tab:red", va="bottom")
        ax.set_ylim(0, limit * 1.12)
        ax.set_title(f"task {t} {specs[t].name}", fontsize=10)
        ax.set_xlabel("score (green: full marks)")
        ax.set_ylabel("completion time [s, simulated]")
    return fig


def _category_points(plt, rows, tasks, specs, table):
    """Per category of tasks: the points available and the mean earned."""
    n_subs = len(table)
    fig, ax = plt.subplots(figsize=(6, 3.6))
    names, got, avail = [], [], []
    for cat, cat_tasks in CATEGORIES.items():
        present = [t for t in cat_tasks if t in tasks]
        if not present:
            continue
        names.append(f"{cat}\n(task{'s' if len(present) > 1 else ''} "
                     f"{', '.join(map(str, present))})")
        avail.append(sum(float(specs[t].max_score) for t in present))
        got.append(sum(sum(e["tasks"][t]["score"] for e in table) / max(1, n_subs)
                       for t in present))
    x = range(len(names))
    ax.bar([i - 0.2 for i in x], avail, 0.4, label="available", color="lightgray")
    bars = ax.bar([i + 0.2 for i in x], got, 0.4, label="average earned", color="tab:blue")
    for b, g, a in zip(bars, got, avail):
        ax.text(b.get_x() + b.get_width() / 2, g + 0.01 * max(avail), f"{g:.1f} / {a:g}",
                ha="center", va="bottom", fontsize=8)
    ax.set_xticks(list(x), names, fontsize=9)
    ax.set_ylabel("points")
    ax.set_ylim(0, max(avail, default=1.0) * 1.15)
    ax.set_title(f"mean over {n_subs} submission{'s' if n_subs != 1 else ''} and the seeds"
                 + (" (task 6 counts in two)" if 6 in tasks else ""), fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    return fig


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
