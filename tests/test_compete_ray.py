"""pr2-drake compete --backend ray: episodes as Ray tasks, the same rows as the local backend.
Skipped where Ray is not installed (it is an optional extra: pip install 'pr2-drake[ray]')."""

import importlib.util
from pathlib import Path

import pytest

from pr2_drake.compete.runner import run_competition

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "submissions"
SAME = ("submission", "task", "seed", "score", "termination", "items", "sim_time", "steps",
        "state_digest")


def test_ray_backend_gives_the_local_rows(tmp_path):
    pytest.importorskip("ray")
    kw = dict(tasks=[1], seeds=[0], seconds=0.2, progress=None)
    local = run_competition(EXAMPLES, out=tmp_path / "local", **kw)
    remote = run_competition(EXAMPLES, out=tmp_path / "ray", jobs=2, backend="ray", **kw)
    assert len(local) == len(remote) == 2
    for a, b in zip(local, remote):
        assert {k: a.get(k) for k in SAME} == {k: b.get(k) for k in SAME}
    assert (tmp_path / "ray" / "results.csv").is_file()
    # Resumed: nothing left to run, the rows are those written.
    again = run_competition(EXAMPLES, out=tmp_path / "ray", backend="ray", **kw)
    assert [r["state_digest"] for r in again] == [r["state_digest"] for r in remote]


def test_backend_arguments_are_checked(tmp_path):
    kw = dict(tasks=[1], seeds=[0], out=tmp_path, progress=None)
    with pytest.raises(ValueError, match="backend must be one of"):
        run_competition(EXAMPLES, backend="slurm", **kw)
    with pytest.raises(ValueError, match="needs backend 'ray'"):
        run_competition(EXAMPLES, ray_address="auto", **kw)
    if importlib.util.find_spec("ray") is None:
        with pytest.raises(ValueError, match=r"pip install 'pr2-drake\[ray\]'"):
            run_competition(EXAMPLES, backend="ray", **kw)
