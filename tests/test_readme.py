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
