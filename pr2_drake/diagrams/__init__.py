"""Declarative wirings: a YAML file names blocks and connects their ports to the testbed.

Example (``diagrams/standing.yaml``)::

    task: 1                # optional; the CLI's --task overrides it
    blocks:
      controller: {class: pr2_drake.controllers.standing:StandingController}
    connect:
      - testbed.joint_state -> controller.joint_state
      - testbed.body_state -> controller.body_state
      - controller.legs_command -> testbed.legs_command
      - controller.arms_command -> testbed.arms_command

Each block's class is built with the keyword arguments it accepts among ``params`` (the
block's ``params`` entry, a path to a YAML file), ``priors``, ``task`` and ``seed``. The
testbed is the block named ``testbed``.
"""

from dataclasses import dataclass, field
from typing import Any

from pydrake.common.yaml import yaml_load_file
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.agents import instantiate_agent, load_agent_class
from pr2_drake.paths import resolve_user_path


@dataclass
class BlockSpec:
    name: str
    cls: str
    params: str | None = None


@dataclass
class DiagramSpec:
    """A parsed diagram YAML."""

    path: str
    task: int | str | None = None
    seed: int | None = None
    blocks: list[BlockSpec] = field(default_factory=list)
    connections: list[tuple[str, str, str, str]] = field(default_factory=list)


def load_diagram_spec(path: str) -> DiagramSpec:
    """Read and check a diagram YAML; errors name the file and the offending entry."""
    file = resolve_user_path(path, "diagram")
    raw = yaml_load_file(str(file))
    unknown = set(raw) - {"task", "seed", "blocks", "connect"}
    if unknown:
        raise ValueError(f"{path}: unknown top-level keys {sorted(unknown)}")
    spec = DiagramSpec(path=str(file), task=raw.get("task"), seed=raw.get("seed"))
    for name, entry in (raw.get("blocks") or {}).items():
        if name == "testbed":
            raise ValueError(f"{path}: 'testbed' is reserved for the testbed itself")
        if not isinstance(entry, dict) or "class" not in entry:
            raise ValueError(f"{path}: block {name!r} needs a 'class: module:Class' entry")
        extra = set(entry) - {"class", "params"}
        if extra:
            raise ValueError(f"{path}: block {name!r} has unknown keys {sorted(extra)}")
        spec.blocks.append(BlockSpec(name, entry["class"], entry.get("params")))
    names = {b.name for b in spec.blocks} | {"testbed"}
    for line in raw.get("connect") or []:
        try:
            src, dst = (part.strip() for part in str(line).split("->"))
            src_block, src_port = src.split(".", 1)
            dst_block, dst_port = dst.split(".", 1)
        except ValueError:
            raise ValueError(f"{path}: connection {line!r} must read 'block.port -> block.port'") from None
        for block in (src_block, dst_block):
            if block not in names:
                raise ValueError(f"{path}: connection {line!r} names unknown block {block!r}")
        spec.connections.append((src_block, src_port, dst_block, dst_port))
    return spec


def wire_diagram(builder: DiagramBuilder, testbed, spec: DiagramSpec, **context: Any) -> dict:
    """Add the spec's blocks to ``builder`` (which already holds ``testbed``) and connect them.

    Returns the blocks by name. Raises ValueError naming a missing port.
    """
    systems = {"testbed": testbed}
    for block in spec.blocks:
        cls = load_agent_class(block.cls)
        available = dict(context)
        if block.params is not None:
            available["params"] = str(resolve_user_path(block.params, f"params of block {block.name!r}"))
        system = instantiate_agent(cls, **available)
        system.set_name(block.name)
        systems[block.name] = builder.AddSystem(system)
    for src_block, src_port, dst_block, dst_port in spec.connections:
        src, dst = systems[src_block], systems[dst_block]
        if not src.HasOutputPort(src_port):
            raise ValueError(f"{spec.path}: {src_block} has no output port {src_port!r}; it has "
                             f"{[src.get_output_port(i).get_name() for i in range(src.num_output_ports())]}")
        if not dst.HasInputPort(dst_port):
            raise ValueError(f"{spec.path}: {dst_block} has no input port {dst_port!r}; it has "
                             f"{[dst.get_input_port(i).get_name() for i in range(dst.num_input_ports())]}")
        builder.Connect(src.GetOutputPort(src_port), dst.GetInputPort(dst_port))
    return systems
