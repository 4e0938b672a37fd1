"""The wheel carries the data folders, so an installed package works outside the checkout."""

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def test_wheel_runs_outside_the_checkout(tmp_path):
    wheels, target = tmp_path / "wheels", tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(wheels),
                    str(REPO)], check=True, timeout=600)
    (wheel,) = wheels.glob("pr2_drake-*.whl")
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target",
                    str(target), str(wheel)], check=True, timeout=600)
    env = dict(os.environ, PYTHONPATH=str(target))
    probe = ("import pr2_drake, pr2_drake.paths as p; "
             "print(pr2_drake.__file__); print(p.data_root())")
    out = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, env=env,
                         capture_output=True, text=True, check=True)
    package_file, root = out.stdout.split()
    assert package_file.startswith(str(target))
    assert root.startswith(str(target)) and root.endswith("share")
    for data in ("models/kuavo/kuavo.urdf", "params/controllers/standing.yaml", "diagrams/standing.yaml"):
        assert (Path(root) / data).is_file()
    run = subprocess.run([sys.executable, "-m", "pr2_drake.cli", "run", "--seconds", "0.05",
                          "--quiet"], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "ended: timeout" in run.stdout
    # The original platform's names ship too, with the per-task controller servers' table.
    probe = ("import pr2, pr2.env, pr2.solver, pr2.tcp; print(pr2.__file__); "
             "from pr2_drake.porting.session import ControllerServerConfig as C; "
             "print(C.for_task(5).overrides)")
    out = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, env=env,
                         capture_output=True, text=True, check=True).stdout.split()
    assert out[0].startswith(str(target)) and out[1] == "walking_stairs.yaml"
