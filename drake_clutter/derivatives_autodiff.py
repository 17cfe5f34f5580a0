"""Exact Jacobians of one phi step by Drake's AutoDiffXd, to validate the finite differences.

Drake steps SAP with AutoDiffXd through hydroelastic contact (compliant boxes against the
rigid hydroelastic arm and shelf: phi's default) and through sphere point contact, but has no
AutoDiffXd Box-Box or Box-Capsule point queries: the "point" contact model cannot be stepped
(the "spheres" one can). ``ToAutoDiffXd()`` drops the PD gains of the arm's actuators; they are
set again on the AutoDiffXd plant before its context is made.

The derivatives are taken in the same tangent coordinates as `derivatives` (see
`dynamics.StateLayout`): each box rotation is seeded as q0 + E(q0) dtheta, and read back as
dtheta' = 4 E(q')^T dq' / |q'|.
"""

from __future__ import annotations

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff

from drake_clutter.dynamics import (
    ARM_DIM,
    BOX_TANGENT,
    NU,
    Phi,
    quaternion_tangent_basis,
)
from drake_clutter.trajectory import robot_positions


def _arm_map() -> np.ndarray:
    """M (9 x 8): ROBOT_JOINTS positions = M @ TRAJECTORY_JOINTS (fingers half the opening)."""
    return np.vstack([robot_positions(row) for row in np.eye(ARM_DIM)]).T


class AutoDiffPhi:
    """An AutoDiffXd copy of a Phi's plant (hydroelastic or spheres contact), built once."""

    def __init__(self, phi: Phi):
        if phi.spec.config.contact_model == "point":
            raise ValueError("AutoDiffXd cannot step phi's 'point' contact model (Drake has no "
                             "AutoDiffXd Box-Box or Box-Capsule point queries): use "
                             "'hydroelastic' or 'spheres'")
        self.phi = phi
        self.diagram = phi.world.diagram.ToAutoDiffXd()
        self.plant = self.diagram.plant()
        self._restore_pd_gains()
        self.root = self.diagram.CreateDefaultContext()
        self.context = self.plant.GetMyMutableContextFromRoot(self.root)
        self.robot = self.plant.GetModelInstanceByName(
            phi.plant.GetModelInstanceName(phi.world.robot))

    def _restore_pd_gains(self) -> None:
        for index in self.phi.plant.GetJointActuatorIndices():
            actuator = self.phi.plant.get_joint_actuator(index)
            if actuator.has_controller():
                self.plant.get_joint_actuator(index).set_controller_gains(
                    actuator.get_controller_gains())

    def jacobians(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(A~ (ndx, ndx), B~ (ndx, nu)) of phi at (x, u), tangent coordinates, exact."""
        phi, layout = self.phi, self.phi.layout
        nz = layout.ndx + NU
        q0, v0 = self._seeded_state(x, u, nz)
        self.plant.SetPositions(self.context, q0)
        self.plant.SetVelocities(self.context, v0)
        self.plant.get_actuation_input_port().FixValue(
            self.context, InitializeAutoDiff(np.zeros(self.plant.num_actuated_dofs()),
                                             np.zeros((self.plant.num_actuated_dofs(), nz))))
        n = phi.spec.config.substeps
        for k in range(n):
            self._fix_desired(x, u, (k + 1) / n, nz)
            state = self.plant.EvalUniquePeriodicDiscreteUpdate(self.context)
            self.context.SetDiscreteState(state.value())
        J = self._read_jacobian(nz)
        return J[:, :layout.ndx], J[:, layout.ndx:]

    def _seeded_state(self, x, u, nz):
        """Positions and velocities as AutoDiffXd vectors seeded with d/d[dx, du]."""
        phi, layout = self.phi, self.phi.layout
        phi.set_state(x, u)  # values, via the double plant
        q, v = phi.plant.GetPositions(phi.context), phi.plant.GetVelocities(phi.context)
        Gq, Gv = np.zeros((len(q), nz)), np.zeros((len(v), nz))
        M, T = _arm_map(), phi.spec.knot_time
        arm_cols, u_cols = slice(0, ARM_DIM), slice(layout.ndx, nz)
        Gq[phi._robot_q, arm_cols] = M
        Gv[phi._robot_v, arm_cols] = -M / T
        Gv[phi._robot_v, u_cols] = M / T
        for i in range(layout.num_boxes):
            c = ARM_DIM + BOX_TANGENT * i
            qi, vi = phi._box_q[i], phi._box_v[i]
            Gq[qi[:4], c:c + 3] = quaternion_tangent_basis(q[qi[:4]])
            Gq[qi[4:], c + 3:c + 6] = np.eye(3)
            Gv[vi, c + 6:c + 12] = np.eye(6)
        return InitializeAutoDiff(q, Gq).ravel(), InitializeAutoDiff(v, Gv).ravel()

    def _fix_desired(self, x, u, s: float, nz: int) -> None:
        layout, M, T = self.phi.layout, _arm_map(), self.phi.spec.knot_time
        x_arm, u = np.asarray(x[:ARM_DIM], dtype=float), np.asarray(u, dtype=float)
        value = np.concatenate([M @ (x_arm + s * (u - x_arm)), M @ (u - x_arm) / T])
        grad = np.zeros((len(value), nz))
        nq = M.shape[0]
        grad[:nq, :ARM_DIM], grad[:nq, layout.ndx:] = (1 - s) * M, s * M
        grad[nq:, :ARM_DIM], grad[nq:, layout.ndx:] = -M / T, M / T
        self.plant.get_desired_state_input_port(self.robot).FixValue(
            self.context, InitializeAutoDiff(value, grad).ravel())

    def _read_jacobian(self, nz: int) -> np.ndarray:
        phi, layout = self.phi, self.phi.layout
        q_ad, v_ad = self.plant.GetPositions(self.context), self.plant.GetVelocities(self.context)
        q, Gq = ExtractValue(q_ad).ravel(), ExtractGradient(q_ad)
        Gv = ExtractGradient(v_ad)
        J = np.zeros((layout.ndx, nz))
        J[:ARM_DIM, layout.ndx:] = np.eye(NU)  # the kinematic arm ends at u
        for i in range(layout.num_boxes):
            r = ARM_DIM + BOX_TANGENT * i
            qi, vi = phi._box_q[i], phi._box_v[i]
            quat = q[qi[:4]]
            norm = np.linalg.norm(quat)
            J[r:r + 3] = 4.0 * quaternion_tangent_basis(quat / norm).T @ Gq[qi[:4]] / norm
            J[r + 3:r + 6] = Gq[qi[4:]]
            J[r + 6:r + 12] = Gv[vi]
        return J
