"""The walking controller's private robot model: kinematics and dynamics terms per tick.

A robot-only continuous MultibodyPlant with one cached Context. ``update(q, v)`` sets the state
once; the ``calc_*`` methods return the terms the whole-body QP needs. Frames: W world, B
base_link, S a sole frame (``l_sole``/``r_sole``, centre of the sole, z up), F a foot body.
Generalized velocities follow the plant: v = [w_WB (3, in W), v_WB (3, in W), joints...].
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable

from pr2_drake.ports import N_ARMS, P_WB, Q_ALL, QUAT_WB, V_ALL, V_WB, W_WB
from pr2_drake.robot.model import BASE_BODY, KuavoMaps, add_kuavo, default_joint_positions
from pr2_drake.robot.params import load_robot_params

SIDES = ("l", "r")


def index_or_slice(idx) -> np.ndarray | slice:
    """``idx`` as a slice when it is a run of consecutive ascending indices (a view, no gather;
    the same values), else as an index array."""
    idx = np.asarray(idx, dtype=int).reshape(-1)
    if len(idx) and np.array_equal(idx, np.arange(idx[0], idx[0] + len(idx))):
        return slice(int(idx[0]), int(idx[0]) + len(idx))
    return idx


class WholeBodyModel:
    """Dynamics terms of KUAVO for the controller (see module docstring)."""

    def __init__(self):
        self.plant = MultibodyPlant(0.0)
        robot = add_kuavo(self.plant)
        self.plant.Finalize()
        self.maps = KuavoMaps.from_plant(self.plant, robot)
        self.context = self.plant.CreateDefaultContext()
        self.nq = self.plant.num_positions()
        self.nv = self.plant.num_velocities()
        self.mass = self.plant.CalcTotalMass(self.context)
        self.world = self.plant.world_frame()
        self.base = self.plant.GetBodyByName(BASE_BODY, robot)
        self.soles = [self.plant.GetFrameByName(f"{s}_sole", robot) for s in SIDES]
        self.hands = [self.plant.GetFrameByName(f"{s}_arm_sphere", robot) for s in SIDES]
        # The arm's first joint frame (on its child body): the shoulder point of reach checks.
        self.shoulders = [self.plant.GetJointByName(f"{s}_shoulder_y", robot).frame_on_child()
                          for s in SIDES]
        self.v_legs = self.maps.v_joints[N_ARMS:]
        self.v_arms = self.maps.v_joints[:N_ARMS]
        self.q_legs = self.maps.q_joints[N_ARMS:]
        foot = load_robot_params().raw["legs"]["foot"]
        r = float(foot["contact_sphere_radius"])
        half = float(foot["length"]) / 2 - r
        # Contact points in the sole frame S (sole level, under the heel and toe spheres).
        if foot.get("contact_layout", "corners") == "line":
            self.p_SC = np.array([[-half, half], [0.0, 0.0], [0.0, 0.0]])
        else:
            w = float(foot["width"]) / 2 - r
            self.p_SC = np.array([[-half, -half, half, half], [w, -w, w, -w], [0.0] * 4])
        self.n_points = self.p_SC.shape[1]
        self.foot_length = float(foot["length"])
        self._g_W = np.array(self.plant.gravity_field().gravity_vector())
        self.gravity = float(-self._g_W[2])  # [m/s^2]
        # Peak torques [Nm] and position limits [rad] of the joints (original order), from the
        # plant's actuators and joints.
        self.effort = np.empty(len(self.maps.v_joints))
        for a in self.plant.GetJointActuatorIndices(robot):
            act = self.plant.get_joint_actuator(a)
            k = list(self.maps.v_joints).index(act.joint().velocity_start())
            self.effort[k] = act.effort_limit()
        self.q_lower = self.plant.GetPositionLowerLimits()[self.maps.q_joints]
        self.q_upper = self.plant.GetPositionUpperLimits()[self.maps.q_joints]
        # Index helpers of the per-tick terms (slices where the indices are consecutive).
        self._q_quat = index_or_slice(self.maps.q_base[:4])
        self._q_pos = index_or_slice(self.maps.q_base[4:])
        self._v_rot = index_or_slice(self.maps.v_base[:3])
        self._v_trans = index_or_slice(self.maps.v_base[3:])
        # Rows of m J_com in M, gathered (a C-ordered copy: M is column-major, and the products
        # below keep the memory layout they had).
        self._com_rows = np.asarray(self.maps.v_base[3:])
        self._inv_mass = 1.0 / self.mass
        self._zero3 = np.zeros(3)
        self.q = np.zeros(self.nq)
        self.v = np.zeros(self.nv)
        self.update(self.plant.GetPositions(self.context).copy(), self.v)
        self.q_nominal = self.plant.GetPositions(self.context).copy()
        self.q_nominal[self.maps.q_joints] = default_joint_positions()

    def state_from_ports(self, joint_state: np.ndarray, body_state: np.ndarray):
        """(q, v) of the plant from the testbed's joint_state (54) and body_state (13)."""
        q = np.empty(self.nq)
        v = np.empty(self.nv)
        m = self.maps
        quat = np.asarray(body_state[QUAT_WB], dtype=float)
        q[self._q_quat] = quat / math.sqrt(quat.dot(quat))  # (np.linalg.norm's own sum)
        q[self._q_pos] = body_state[P_WB]
        q[m.q_joints] = joint_state[Q_ALL]
        v[self._v_rot] = body_state[W_WB]
        v[self._v_trans] = body_state[V_WB]
        v[m.v_joints] = joint_state[V_ALL]
        return q, v

    def update(self, q: np.ndarray, v: np.ndarray) -> None:
        """Set the state; the terms below are computed at most once per update (cached)."""
        self.q, self.v = q, v
        self.plant.SetPositionsAndVelocities(self.context, np.concatenate([q, v]))
        self._M = self._Cv = self._h = self._com = self._R_WB = None
        self._X_WS = [None, None]
        self._sole = [None, None]
        self._hand = [None, None]
        self._hand_rot = [None, None]

    # ---- terms (cached per update: treat the returned arrays as read-only) -------------------
    def mass_matrix(self) -> np.ndarray:
        if self._M is None:
            self._M = self.plant.CalcMassMatrix(self.context)
        return self._M

    def _bias_term(self) -> np.ndarray:
        """C(q, v) v."""
        if self._Cv is None:
            self._Cv = self.plant.CalcBiasTerm(self.context)
        return self._Cv

    def bias(self) -> np.ndarray:
        """h = C(q, v) v - tau_g(q), so that M vdot + h = B u + J^T f.

        Gravity is uniform, so tau_g = sum_i m_i J_i^T g = m J_com^T g = M[v_WB rows]^T g
        (see :meth:`com`; exact, and cheaper than CalcGravityGeneralizedForces).
        """
        if self._h is None:
            M_t = self.mass_matrix()[self._com_rows]
            self._h = self._bias_term() - np.dot(M_t.T, self._g_W)
        return self._h

    def com(self):
        """p_WCcm, v_WCcm, J (3 x nv) and Jdot v (3) of the centre of mass, in W.

        With the floating base's translational velocity v_WB in W among the generalized
        velocities, the translational rows of the equations of motion are the whole robot's
        force balance, m a_Ccm = sum of external forces: so those rows of M are m J and those
        of C v are m Jdot v (exact; ~0.06 ms cheaper than Drake's CoM bias acceleration).
        """
        if self._com is None:
            p = self.plant.CalcCenterOfMassPositionInWorld(self.context)
            rows = self._com_rows
            J = self.mass_matrix()[rows] * self._inv_mass
            jdv = self._bias_term()[rows] * self._inv_mass
            self._com = (p, np.dot(J, self.v), J, jdv)
        return self._com

    def sole_pose(self, side: int) -> RigidTransform:
        """X_WS of sole ``side`` (0 left, 1 right)."""
        X = self._X_WS[side]
        if X is None:
            X = self._X_WS[side] = self.soles[side].CalcPoseInWorld(self.context)
        return X

    def sole_spatial(self, side: int):
        """X_WS, V_WS (6: [w; v] in W), J (6 x nv) and Jdot v (6) of a sole frame."""
        if self._sole[side] is None:
            ctx, W, S = self.context, self.world, self.soles[side]
            J = self.plant.CalcJacobianSpatialVelocity(
                ctx, JacobianWrtVariable.kV, S, self._zero3, W, W)
            jdv = self.plant.CalcBiasSpatialAcceleration(
                ctx, JacobianWrtVariable.kV, S, self._zero3, W, W).get_coeffs()
            self._sole[side] = (self.sole_pose(side), np.dot(J, self.v), J, jdv)
        return self._sole[side]

    def shoulder_position(self, side: int) -> np.ndarray:
        """p_WS of the shoulder (first arm joint) of one side [m]."""
        return self.shoulders[side].CalcPoseInWorld(self.context).translation()

    def hand_point(self, side: int):
        """p_WH, v_WH (3, W), J (3 x nv) and Jdot v (3) of a hand sphere centre H."""
        if self._hand[side] is None:
            ctx, W, H = self.context, self.world, self.hands[side]
            J = self.plant.CalcJacobianTranslationalVelocity(
                ctx, JacobianWrtVariable.kV, H, self._zero3, W, W)
            jdv = self.plant.CalcBiasTranslationalAcceleration(
                ctx, JacobianWrtVariable.kV, H, self._zero3, W, W).reshape(-1)
            p = H.CalcPoseInWorld(ctx).translation()
            self._hand[side] = (p, np.dot(J, self.v), J, jdv)
        return self._hand[side]

    def hand_rotation(self, side: int):
        """R_WH (3 x 3), w_WH (3, W), J_w (3 x nv) and Jdot_w v (3) of a hand sphere frame H."""
        if self._hand_rot[side] is None:
            ctx, W, H = self.context, self.world, self.hands[side]
            J = self.plant.CalcJacobianSpatialVelocity(
                ctx, JacobianWrtVariable.kV, H, self._zero3, W, W)[:3]
            jdv = self.plant.CalcBiasSpatialAcceleration(
                ctx, JacobianWrtVariable.kV, H, self._zero3, W, W).rotational()
            R = H.CalcPoseInWorld(ctx).rotation().matrix()
            # (J is a strided view: keep @, whose sum for it differs from np.dot's)
            self._hand_rot[side] = (R, J @ self.v, J, np.asarray(jdv).reshape(-1))
        return self._hand_rot[side]

    def contact_points(self, side: int):
        """J (3n x nv) and Jdot v (3n) of the contact points of one sole, stacked per point."""
        ctx, W, S = self.context, self.world, self.soles[side]
        J = self.plant.CalcJacobianTranslationalVelocity(
            ctx, JacobianWrtVariable.kV, S, self.p_SC, W, W)
        jdv = self.plant.CalcBiasTranslationalAcceleration(
            ctx, JacobianWrtVariable.kV, S, self.p_SC, W, W)
        return J, jdv.T.reshape(-1)

    def contact_heights(self, side: int) -> np.ndarray:
        """z in W of the contact points of one sole [m]."""
        X = self.sole_pose(side)
        return np.dot(X.rotation().matrix(), self.p_SC)[2] + X.translation()[2]

    def base_pose(self) -> RigidTransform:
        return self.base.EvalPoseInWorld(self.context)

    def base_rotation(self) -> np.ndarray:
        """R_WB (3x3) from the base quaternion in q (no kinematics evaluation; cached)."""
        if self._R_WB is not None:
            return self._R_WB
        w, x, y, z = self.q[self.maps.q_base[:4]].tolist()
        n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w * n, x * n, y * n, z * n
        self._R_WB = np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        return self._R_WB
