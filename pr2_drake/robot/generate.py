"""Generate the KUAVO URDF from models/kuavo/params.yaml.

Usage::

    python -m pr2_drake.robot.generate            # rewrites models/kuavo/kuavo.urdf
    python -m pr2_drake.robot.generate --check    # exits 1 if the committed URDF is stale

Links and frames (x forward, y left, z up):

- ``base_link``: the floating base (pelvis, trunk and head), origin between the hips.
- ``{l,r}_hip_yaw_link``, ``{l,r}_hip_roll_link``, ``{l,r}_thigh``, ``{l,r}_calf``,
  ``{l,r}_foot``: the legs. Each foot collides through four corner spheres on its sole; the
  frame ``{l,r}_sole`` sits at the centre of the sole, on the ground plane when the foot is flat.
- ``{l,r}_shoulder_pitch_link``, ``{l,r}_shoulder_roll_link``, ``{l,r}_upper_arm``,
  ``{l,r}_forearm`` and ``{l,r}_arm_sphere`` (the end effectors, at the hand sphere centre).
- ``head_camera``: the RGB-D camera frame in Drake's camera convention (+z optical axis,
  +x image right, +y image down).

All robot links share one collision filter group: the robot does not collide with itself.

Visuals: the trunk, thighs, calves, feet, upper arms and forearms are shell meshes generated from
the same parameters (:mod:`pr2_drake.robot.shells`, written to ``models/kuavo/meshes``); the
collision geometry stays boxes, cylinders and spheres.
"""

from __future__ import annotations

import argparse
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from pydrake.math import RollPitchYaw, RotationMatrix

from pr2_drake.paths import data_path
from pr2_drake.robot.params import RobotParams, load_robot_params

SIDES = {"l": 1.0, "r": -1.0}
COLORS = {
    "shell": (0.92, 0.92, 0.94, 1.0),
    "joint": (0.18, 0.18, 0.2, 1.0),
    "accent": (0.1, 0.35, 0.75, 1.0),
    "visor": (0.05, 0.05, 0.08, 1.0),
    "sole": (0.25, 0.25, 0.28, 1.0),
    "hand": (0.85, 0.55, 0.1, 1.0),
}


def _fmt(values) -> str:
    return " ".join(f"{float(v):.6g}" for v in values)


def _box_inertia(m: float, size) -> tuple[float, float, float]:
    a, b, c = size
    return (m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12)


def _cylinder_inertia(m: float, r: float, h: float) -> tuple[float, float, float]:
    side = m * (3 * r * r + h * h) / 12
    return (side, side, m * r * r / 2)


def _sphere_inertia(m: float, r: float) -> tuple[float, float, float]:
    i = 2 * m * r * r / 5
    return (i, i, i)


class _UrdfWriter:
    def __init__(self, name: str):
        self.robot = ET.Element("robot", {"name": name, "xmlns:drake": "http://drake.mit.edu"})
        self.links: list[str] = []
        for color, rgba in COLORS.items():
            mat = ET.SubElement(self.robot, "material", {"name": color})
            ET.SubElement(mat, "color", {"rgba": _fmt(rgba)})

    def link(self, name: str, mass: float | None = None, com=(0, 0, 0), inertia=(0, 0, 0)):
        link = ET.SubElement(self.robot, "link", {"name": name})
        if mass is not None:
            inertial = ET.SubElement(link, "inertial")
            ET.SubElement(inertial, "origin", {"xyz": _fmt(com), "rpy": "0 0 0"})
            ET.SubElement(inertial, "mass", {"value": f"{mass:.6g}"})
            ixx, iyy, izz = inertia
            ET.SubElement(
                inertial, "inertia",
                {"ixx": f"{ixx:.6g}", "iyy": f"{iyy:.6g}", "izz": f"{izz:.6g}",
                 "ixy": "0", "ixz": "0", "iyz": "0"},
            )
        self.links.append(name)
        return link

    @staticmethod
    def shape(link, kind: str, geometry: dict, xyz=(0, 0, 0), rpy=(0, 0, 0), color=None,
              name: str | None = None):
        attrs = {"name": name} if name else {}
        el = ET.SubElement(link, kind, attrs)
        ET.SubElement(el, "origin", {"xyz": _fmt(xyz), "rpy": _fmt(rpy)})
        geo = ET.SubElement(el, "geometry")
        (shape_name, shape_attrs), = geometry.items()
        ET.SubElement(geo, shape_name, {k: v if isinstance(v, str) else _fmt(np.atleast_1d(v))
                                        for k, v in shape_attrs.items()})
        if color is not None:
            ET.SubElement(el, "material", {"name": color})
        return el

    def fixed(self, name: str, parent: str, child: str, xyz=(0, 0, 0), rpy=(0, 0, 0)):
        j = ET.SubElement(self.robot, "joint", {"name": name, "type": "fixed"})
        ET.SubElement(j, "parent", {"link": parent})
        ET.SubElement(j, "child", {"link": child})
        ET.SubElement(j, "origin", {"xyz": _fmt(xyz), "rpy": _fmt(rpy)})

    def revolute(self, name: str, parent: str, child: str, xyz, axis, lower, upper, effort,
                 velocity, damping: float, rotor_inertia: float):
        j = ET.SubElement(self.robot, "joint", {"name": name, "type": "revolute"})
        ET.SubElement(j, "parent", {"link": parent})
        ET.SubElement(j, "child", {"link": child})
        ET.SubElement(j, "origin", {"xyz": _fmt(xyz), "rpy": "0 0 0"})
        ET.SubElement(j, "axis", {"xyz": _fmt(axis)})
        ET.SubElement(
            j, "limit",
            {"lower": f"{lower:.6g}", "upper": f"{upper:.6g}", "effort": f"{effort:.6g}",
             "velocity": f"{velocity:.6g}"},
        )
        ET.SubElement(j, "dynamics", {"damping": f"{damping:.6g}"})
        tr = ET.SubElement(self.robot, "transmission", {"name": f"{name}_transmission"})
        ET.SubElement(tr, "type").text = "transmission_interface/SimpleTransmission"
        tj = ET.SubElement(tr, "joint", {"name": name})
        ET.SubElement(tj, "hardwareInterface").text = "hardware_interface/EffortJointInterface"
        act = ET.SubElement(tr, "actuator", {"name": name})
        ET.SubElement(act, "mechanicalReduction").text = "1"
        ET.SubElement(act, "drake:rotor_inertia", {"value": f"{rotor_inertia:.6g}"})
        ET.SubElement(act, "drake:gear_ratio", {"value": "1"})

    def finish(self) -> str:
        group = ET.SubElement(self.robot, "drake:collision_filter_group", {"name": "robot_self"})
        for link in self.links:
            ET.SubElement(group, "drake:member", {"link": link})
        ET.SubElement(group, "drake:ignored_collision_filter_group", {"name": "robot_self"})
        ET.indent(self.robot, space="  ")
        header = (
            "<?xml version=\"1.0\"?>\n"
            "<!-- Generated by `python -m pr2_drake.robot.generate` from models/kuavo/params.yaml."
            " Do not edit by hand. -->\n"
        )
        return header + ET.tostring(self.robot, encoding="unicode") + "\n"


def _mirror_axis(axis, side_sign: float) -> tuple[float, float, float]:
    """Axis of the right-side joint: the mirror image (a pseudo-vector) of the left axis."""
    ax, ay, az = axis
    if side_sign > 0:
        return (ax, ay, az)
    return (-ax, ay, -az)


MESH_DIR = "meshes"  # shell meshes, next to the URDF (pr2_drake.robot.shells)


def _shell(stem: str) -> dict:
    """URDF geometry of a shell mesh (in its link's frame; visual only)."""
    return {"mesh": {"filename": f"{MESH_DIR}/{stem}.obj"}}


def write_shells(params: RobotParams, urdf_path: Path, check: bool = False) -> list[Path]:
    """Write the shell meshes next to ``urdf_path``; with ``check``, write nothing and return
    the stale files."""
    from pr2_drake.robot.shells import shell_meshes, write_obj

    folder = urdf_path.parent / MESH_DIR
    folder.mkdir(parents=True, exist_ok=True)
    stale = []
    for stem, (verts, faces) in shell_meshes(params.raw).items():
        path = folder / f"{stem}.obj"
        tmp = folder / f".{stem}.obj.tmp"
        write_obj(tmp, verts, faces, f"KUAVO {stem} shell [m], in the {stem} link frame")
        if check:
            if not path.is_file() or path.read_text() != tmp.read_text():
                stale.append(path)
            tmp.unlink()
        else:
            tmp.replace(path)
    return stale


def build_urdf(params: RobotParams) -> str:
    """Return the URDF text for the given parameters (shell meshes: :func:`write_shells`)."""
    p = params.raw
    w = _UrdfWriter(p["name"])
    _add_torso(w, p["torso"])
    _add_head_camera(w, p["head_camera"])
    joints = {j.name: j for j in params.joints}

    def revolute(name: str, parent: str, child: str, xyz, side_sign: float, group: str):
        spec = joints[name]
        w.revolute(name, parent, child, xyz, _mirror_axis(spec.axis, side_sign), spec.lower,
                   spec.upper, spec.effort, spec.velocity,
                   damping=p["actuators"][group]["joint_damping"],
                   rotor_inertia=p["actuators"][group]["reflected_inertia"])

    for s, sign in SIDES.items():
        _add_leg(w, p, s, sign, revolute)
        _add_arm(w, p, s, sign, revolute)
    return w.finish()


def _add_torso(w: _UrdfWriter, torso: dict) -> None:
    """The floating base: pelvis, trunk and head."""
    base = w.link("base_link", torso["mass"], torso["com"],
                  _box_inertia(torso["mass"], torso["trunk_size"]))
    w.shape(base, "visual", _shell("trunk"), color="shell")
    w.shape(base, "visual", {"box": {"size": torso["pelvis_size"]}}, torso["pelvis_center"],
            color="joint")
    w.shape(base, "visual", {"sphere": {"radius": torso["head_radius"]}}, torso["head_center"],
            color="shell")
    hx, hy, hz = torso["head_center"]
    r_head = torso["head_radius"]
    w.shape(base, "visual", {"box": {"size": [0.03, 1.3 * r_head, 0.45 * r_head]}},
            (hx + 0.85 * r_head, hy, hz + 0.1 * r_head), color="visor")
    tx, ty, tz = torso["trunk_center"]
    sx, sy, sz = torso["trunk_size"]
    w.shape(base, "visual", {"box": {"size": [0.01, 0.6 * sy, 0.08]}},
            (tx + sx / 2, ty, tz + 0.15 * sz), color="accent")
    w.shape(base, "collision", {"box": {"size": torso["trunk_size"]}}, torso["trunk_center"])
    w.shape(base, "collision", {"sphere": {"radius": r_head}}, torso["head_center"])


def _add_head_camera(w: _UrdfWriter, cam: dict) -> None:
    """The head camera's optical frame, fixed in base_link."""
    theta = np.radians(cam["pitch_deg"])
    # Camera optical frame C in base B: z_C forward-and-down, x_C to the robot's right.
    z_c = np.array([np.cos(theta), 0.0, -np.sin(theta)])
    x_c = np.array([0.0, -1.0, 0.0])
    y_c = np.cross(z_c, x_c)
    R_BC = RotationMatrix(np.column_stack([x_c, y_c, z_c]))
    w.link("head_camera")
    w.fixed("head_camera_mount", "base_link", "head_camera", cam["position"],
            RollPitchYaw(R_BC).vector())


def _add_leg(w: _UrdfWriter, p: dict, s: str, sign: float, revolute) -> None:
    """One leg (side ``s``; ``sign`` +1 left): hip yaw -> hip roll -> hip pitch (co-located)
    -> knee -> ankle pitch, the foot's contact spheres and the sole frame."""
    torso, legs = p["torso"], p["legs"]
    foot = legs["foot"]
    hip_xyz = (0.0, sign * torso["pelvis_width"] / 2, torso["hip_offset_z"])
    m = legs["hip_yaw_link_mass"]
    link = w.link(f"{s}_hip_yaw_link", m, (0, 0, 0.02), _cylinder_inertia(m, 0.04, 0.06))
    w.shape(link, "visual", {"cylinder": {"radius": 0.04, "length": 0.06}}, (0, 0, 0.02),
            color="joint")
    revolute(f"{s}_hip_z", "base_link", f"{s}_hip_yaw_link", hip_xyz, sign, "legs")

    m = legs["hip_roll_link_mass"]
    link = w.link(f"{s}_hip_roll_link", m, (0, 0, 0), _sphere_inertia(m, 0.05))
    w.shape(link, "visual", {"cylinder": {"radius": 0.045, "length": 0.09}}, (0, 0, 0),
            (np.pi / 2, 0, 0), color="joint")
    revolute(f"{s}_hip_x", f"{s}_hip_yaw_link", f"{s}_hip_roll_link", (0, 0, 0), sign, "legs")

    th = legs["thigh"]
    link = w.link(f"{s}_thigh", th["mass"], (0, 0, -th["length"] / 2),
                  _cylinder_inertia(th["mass"], th["radius"], th["length"]))
    w.shape(link, "visual", _shell("thigh"), color="shell")
    w.shape(link, "collision",
            {"cylinder": {"radius": th["radius"], "length": th["length"] - 0.06}},
            (0, 0, -th["length"] / 2))
    revolute(f"{s}_hip_y", f"{s}_hip_roll_link", f"{s}_thigh", (0, 0, 0), sign, "legs")

    ca = legs["calf"]
    link = w.link(f"{s}_calf", ca["mass"], (0, 0, -ca["length"] / 2),
                  _cylinder_inertia(ca["mass"], ca["radius"], ca["length"]))
    w.shape(link, "visual", _shell("calf"), color="shell")
    w.shape(link, "visual", {"sphere": {"radius": ca["radius"] * 1.15}}, (0, 0, 0),
            color="joint")
    w.shape(link, "collision",
            {"cylinder": {"radius": ca["radius"], "length": ca["length"] - 0.06}},
            (0, 0, -ca["length"] / 2))
    revolute(f"{s}_knee", f"{s}_thigh", f"{s}_calf", (0, 0, -th["length"]), sign, "legs")

    fl, fw, fh, heel = foot["length"], foot["width"], foot["ankle_height"], foot["heel"]
    r = foot["contact_sphere_radius"]
    x_mid = -heel + fl / 2
    sole_thickness = 0.03
    link = w.link(f"{s}_foot", foot["mass"], (x_mid, 0, -fh + sole_thickness),
                  _box_inertia(foot["mass"], (fl, fw, 2 * sole_thickness)))
    w.shape(link, "visual", {"box": {"size": [fl, fw, sole_thickness]}},
            (x_mid, 0, -fh + sole_thickness / 2), color="sole")
    w.shape(link, "visual", {"cylinder": {"radius": 0.03, "length": fh}},
            (0, 0, -fh / 2), color="joint")
    w.shape(link, "visual", _shell("foot"), color="shell")
    layout = foot.get("contact_layout", "corners")
    if layout not in ("corners", "line"):
        raise ValueError(f"legs.foot.contact_layout must be 'corners' or 'line', got {layout!r}")
    for ix, x in enumerate((-heel + r, -heel + fl - r)):
        if layout == "line":
            # Heel and toe spheres on the centre line: the foot rolls about its long axis.
            w.shape(link, "collision", {"sphere": {"radius": r}}, (x, 0.0, -fh + r),
                    name=f"{s}_foot_contact_{'ht'[ix]}")
            continue
        for iy, y in enumerate((fw / 2 - r, -(fw / 2 - r))):
            w.shape(link, "collision", {"sphere": {"radius": r}}, (x, y, -fh + r),
                    name=f"{s}_foot_contact_{'ht'[ix]}{'lr'[iy]}")
    revolute(f"{s}_ankle", f"{s}_calf", f"{s}_foot", (0, 0, -ca["length"]), sign, "legs")
    w.link(f"{s}_sole")
    w.fixed(f"{s}_sole_frame", f"{s}_foot", f"{s}_sole", (x_mid, 0, -fh))


def _add_arm(w: _UrdfWriter, p: dict, s: str, sign: float, revolute) -> None:
    """One arm: shoulder pitch -> shoulder roll -> shoulder yaw (co-located) -> elbow, and the
    hand sphere."""
    torso, arms = p["torso"], p["arms"]
    sh = torso["shoulder_offset"]
    m = arms["shoulder_link_mass"]
    link = w.link(f"{s}_shoulder_pitch_link", m, (0, 0, 0), _sphere_inertia(m, 0.04))
    w.shape(link, "visual", {"sphere": {"radius": 0.045}}, (0, 0, 0), color="joint")
    revolute(f"{s}_shoulder_y", "base_link", f"{s}_shoulder_pitch_link",
             (sh[0], sign * sh[1], sh[2]), sign, "arms")
    link = w.link(f"{s}_shoulder_roll_link", m, (0, 0, 0), _sphere_inertia(m, 0.04))
    revolute(f"{s}_shoulder_x", f"{s}_shoulder_pitch_link", f"{s}_shoulder_roll_link",
             (0, 0, 0), sign, "arms")
    ua = arms["upper_arm"]
    link = w.link(f"{s}_upper_arm", ua["mass"], (0, 0, -ua["length"] / 2),
                  _cylinder_inertia(ua["mass"], ua["radius"], ua["length"]))
    w.shape(link, "visual", _shell("upper_arm"), color="shell")
    w.shape(link, "collision",
            {"cylinder": {"radius": ua["radius"], "length": ua["length"] - 0.05}},
            (0, 0, -ua["length"] / 2))
    revolute(f"{s}_shoulder_z", f"{s}_shoulder_roll_link", f"{s}_upper_arm", (0, 0, 0), sign,
             "arms")
    fa = arms["forearm"]
    link = w.link(f"{s}_forearm", fa["mass"], (0, 0, -fa["length"] / 2),
                  _cylinder_inertia(fa["mass"], fa["radius"], fa["length"]))
    w.shape(link, "visual", _shell("forearm"), color="shell")
    w.shape(link, "visual", {"sphere": {"radius": fa["radius"] * 1.2}}, (0, 0, 0),
            color="joint")
    w.shape(link, "collision",
            {"cylinder": {"radius": fa["radius"], "length": fa["length"] - 0.06}},
            (0, 0, -fa["length"] / 2))
    revolute(f"{s}_elbow", f"{s}_upper_arm", f"{s}_forearm", (0, 0, -ua["length"]), sign,
             "arms")
    hs = arms["hand_sphere"]
    link = w.link(f"{s}_arm_sphere", hs["mass"], (0, 0, 0),
                  _sphere_inertia(hs["mass"], hs["radius"]))
    w.shape(link, "visual", {"sphere": {"radius": hs["radius"]}}, (0, 0, 0), color="hand")
    w.shape(link, "collision", {"sphere": {"radius": hs["radius"]}}, (0, 0, 0))
    w.fixed(f"{s}_hand_mount", f"{s}_forearm", f"{s}_arm_sphere", (0, 0, -fa["length"]))


def default_urdf_path() -> Path:
    return data_path("models", "kuavo", "kuavo.urdf")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--params", help="parameter file (default: models/kuavo/params.yaml)")
    parser.add_argument("--out", help="output URDF (default: models/kuavo/kuavo.urdf)")
    parser.add_argument("--check", action="store_true",
                        help="do not write; exit 1 if the output file differs")
    args = parser.parse_args(argv)
    params = load_robot_params(args.params)
    text = build_urdf(params)
    out = Path(args.out) if args.out else default_urdf_path()
    if args.check:
        current = out.read_text() if out.is_file() else ""
        if current != text or write_shells(params, out, check=True):
            print(f"{out} is stale: run python -m pr2_drake.robot.generate", file=sys.stderr)
            return 1
        print(f"{out} is up to date")
        return 0
    out.write_text(text)
    write_shells(params, out)
    print(f"wrote {out} and its shell meshes in {out.parent / MESH_DIR}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
