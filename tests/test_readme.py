"""Every Python snippet in the README runs as written (long simulations shortened)."""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
SNIPPETS = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
SHORTEN = {"AdvanceTo(10.0)": "AdvanceTo(0.5)", "seconds=5.0": "seconds=1.0"}


def test_the_readme_has_python_snippets():
    assert len(SNIPPETS) >= 3


@pytest.mark.parametrize("index", range(len(SNIPPETS)))
def test_readme_snippet_runs(index, tmp_path, monkeypatch):
    code = SNIPPETS[index]
    if "register_task(" in code:
        pytest.skip("needs the files of its recipe: test_adding_a_task_as_the_readme_says")
    for long, short in SHORTEN.items():
        code = code.replace(long, short)
    monkeypatch.chdir(tmp_path)
    exec(compile(code, f"README.md python snippet {index}", "exec"), {"__name__": "readme"})


def test_hold_still_runs_from_a_file_as_the_readme_says(tmp_path):
    from pr2_drake.run import run_episode
    from pr2_drake.scenario import Scenario

    snippet = next(s for s in SNIPPETS if "class HoldStill" in s)
    agent_code = snippet.split("env = Env(")[0].replace("from pr2_drake.env import Env\n", "")
    (tmp_path / "hold.py").write_text(agent_code)
    report = run_episode(Scenario(task=1, seed=7, agent=f"{tmp_path / 'hold.py'}:HoldStill",
                                  seconds=0.5))
    assert report["termination"] == "timeout" and report["agent"].endswith("hold.py:HoldStill")


def test_adding_a_task_as_the_readme_says(tmp_path, monkeypatch):
    """The "Adding a task" recipe, its files written as the README names them: the toy task
    is listed, built with its scene and referee, and its default agent completes it."""
    from pr2_drake import tasks

    section = README.read_text().split("## Adding a task")[1].split("\n## ")[0]
    spec = re.findall(r"```yaml\n(.*?)```", section, re.S)[0]
    module, run = re.findall(r"```python\n(.*?)```", section, re.S)
    (tmp_path / "toy_walk.yaml").write_text(spec)
    (tmp_path / "toy_walk.py").write_text(module)
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(tasks, "_ROWS", dict(tasks._rows()))  # the row goes with the test
    scope = {"__name__": "readme"}
    exec(compile(run, "README.md: Adding a task", "exec"), scope)
    assert (7, "toy_walk") in tasks.list_tasks()
    report = scope["report"]
    assert report["task_name"] == "toy_walk" and report["agent"].endswith("WalkToGoalAgent")
    assert report["termination"] == "completed" and report["score"] == 10.0
    assert [e["item"] for e in report["items"]] == ["goal"]
