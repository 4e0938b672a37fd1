"""Which modules of pr2_drake a scenario passes through from ``run_episode`` to the plant.

    python tools/scenario_path.py [--task 1] [--agent SPEC] [--diagram YAML]

Runs one episode (0.002 s) under a call tracer and prints: the chain of pr2_drake modules on
the call stack when the MultibodyPlant is built, the pr2_drake modules called from
``run_episode``'s start until then, and how often ``Scenario.validate`` ran in the episode.
Works on any commit (``run_episode`` from pr2_drake.run or pr2_drake.episode).
"""

import argparse
import sys


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--task", default="1")
    p.add_argument("--agent", default=None)
    p.add_argument("--diagram", default=None)
    a = p.parse_args()
    import pydrake.multibody.plant as mbp

    try:
        from pr2_drake.run import run_episode
    except ImportError:
        from pr2_drake.episode import run_episode
    from pr2_drake.scenario import Scenario

    seen: list[str] = []
    chain: list[str] = []
    validations = [0]
    done = [False]

    def module_of(frame) -> str | None:
        name = frame.f_globals.get("__name__", "")
        return name if name.startswith("pr2_drake") else None

    def tracer(frame, event, arg):
        if event == "call":
            mod = module_of(frame)
            if mod and frame.f_code.co_name == "validate" and "scenario" in mod:
                validations[0] += 1
            if mod and not done[0] and frame.f_code.co_name != "<module>" and mod not in seen:
                seen.append(mod)  # (imports are not steps of the scenario)
        elif event == "c_call" and not done[0] and getattr(arg, "__name__", "") in (
                "AddMultibodyPlant", "AddMultibodyPlantSceneGraph", "MultibodyPlant"):
            done[0] = True
            f = frame
            while f is not None:
                mod = module_of(f)
                if mod and (not chain or chain[-1] != mod):
                    chain.append(mod)
                f = f.f_back
        return tracer

    del mbp
    scenario = Scenario(task=int(a.task) if a.task.isdigit() else a.task, seed=0, seconds=0.002,
                        agent=a.agent, diagram=a.diagram)
    sys.setprofile(tracer)
    try:
        run_episode(scenario)
    finally:
        sys.setprofile(None)
    print("call chain when the plant is built:", " -> ".join(reversed(chain)),
          f"({len(set(chain))} modules)")
    print(f"modules whose functions ran before the plant ({len(seen)}):", ", ".join(seen))
    print("Scenario.validate calls in the episode:", validations[0])
    return 0


if __name__ == "__main__":
    sys.exit(main())
