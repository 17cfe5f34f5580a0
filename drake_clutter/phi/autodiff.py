"""Exact Jacobians of one phi step by Drake's AutoDiffXd: phi's derivatives when
``DynamicsConfig.derivative_method`` is "autodiff", and the reference for the finite differences.

Drake steps SAP with AutoDiffXd through hydroelastic contact (compliant boxes against the
rigid hydroelastic arm and shelf: phi's default) and through sphere point contact, but has no
AutoDiffXd Box-Box or Box-Capsule point queries: the "point" contact model cannot be stepped
(the "spheres" one can). ``ToAutoDiffXd()`` drops the PD gains of the arm's actuators; they are
set again on the AutoDiffXd plant before its context is made.

The derivatives are taken in the same tangent coordinates as `derivatives` (see
`state.StateLayout`): each box rotation is seeded as q0 + E(q0) dtheta, and read back as
dtheta' = 4 E(q')^T dq' / |q'|.

`AutoDiffPhi.directional` seeds only chosen directions of [dx, du] (the colour groups of
`derivatives`: one direction sums the columns of a group, which never share a row), so a knot
costs one AutoDiffXd step with as many derivative slots as the knot has groups instead of
ndx + nu; it also differentiates the contact forces f of `dynamics.Phi.contact_forces` and the
speed cap of `dynamics.Phi._speed_capped`, so the result is a drop-in for finite differences.
"""

from __future__ import annotations

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff

from drake_clutter.phi.dynamics import Phi
from drake_clutter.phi.state import ARM_DIM, BOX_TANGENT, NU, quaternion_tangent_basis
from drake_clutter.trajectory import robot_positions
from drake_clutter.worlds.drake_world import contact_pairs


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
        ndx = self.phi.layout.ndx
        J = self.directional(x, u, np.eye(ndx + NU))[:ndx]
        return J[:, :ndx], J[:, ndx:]

    def directional(self, x: np.ndarray, u: np.ndarray, S: np.ndarray) -> np.ndarray:
        """d[x' (tangent), f] / d[dx, du] times the seed directions S ((ndx + nu) x m): shape
        (ndx + nf, m), nf = `Phi.num_forces` (f in N, averaged over the knot like
        `Phi.step_full`). All NaN where the AutoDiffXd step fails or is not finite."""
        phi, layout = self.phi, self.phi.layout
        S = np.asarray(S, dtype=float)
        m = S.shape[1]
        out = np.full((layout.ndx + phi.num_forces, m), np.nan)
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(u))):
            return out
        q0, v0 = self._seeded_state(x, u, S)
        self.plant.SetPositions(self.context, q0)
        self.plant.SetVelocities(self.context, v0)
        self.plant.get_actuation_input_port().FixValue(
            self.context, InitializeAutoDiff(np.zeros(self.plant.num_actuated_dofs()),
                                             np.zeros((self.plant.num_actuated_dofs(), m))))
        n = phi.spec.config.substeps
        dforces = np.zeros((phi.num_forces, m))
        try:
            for k in range(n):
                self._fix_desired(x, u, (k + 1) / n, S)
                state = self.plant.EvalUniquePeriodicDiscreteUpdate(self.context)
                dforces += self._force_gradient(m)
                self.context.SetDiscreteState(self._speed_capped(state.value(), m))
        except RuntimeError:
            return out
        out[:layout.ndx] = self._read_jacobian(S)
        out[layout.ndx:] = dforces / n
        return out if np.all(np.isfinite(out)) else np.full_like(out, np.nan)

    def _seeded_state(self, x, u, S):
        """Positions and velocities as AutoDiffXd vectors seeded with d/d[dx, du] S."""
        phi, layout = self.phi, self.phi.layout
        nz = layout.ndx + NU
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
        return InitializeAutoDiff(q, Gq @ S).ravel(), InitializeAutoDiff(v, Gv @ S).ravel()

    def _fix_desired(self, x, u, s: float, S: np.ndarray) -> None:
        layout, M, T = self.phi.layout, _arm_map(), self.phi.spec.knot_time
        x_arm, u = np.asarray(x[:ARM_DIM], dtype=float), np.asarray(u, dtype=float)
        value = np.concatenate([M @ (x_arm + s * (u - x_arm)), M @ (u - x_arm) / T])
        grad = np.zeros((len(value), layout.ndx + NU))
        nq = M.shape[0]
        grad[:nq, :ARM_DIM], grad[:nq, layout.ndx:] = (1 - s) * M, s * M
        grad[nq:, :ARM_DIM], grad[nq:, layout.ndx:] = -M / T, M / T
        self.plant.get_desired_state_input_port(self.robot).FixValue(
            self.context, InitializeAutoDiff(value, grad @ S).ravel())

    def _speed_capped(self, values: np.ndarray, m: int) -> np.ndarray:
        """`Phi._speed_capped` on AutoDiffXd values: a capped speed's gradient is that of
        v cap / |v| (its component along v removed, scaled by cap / |v|)."""
        phi = self.phi
        if not len(phi._box_v):
            return values
        value, grad = ExtractValue(values).ravel(), _gradient(values, m)
        capped = phi._speed_capped(value)
        if capped is value:
            return values
        cfg = phi.spec.config
        for vi in phi._box_v:
            for rows, cap in ((phi._nq + vi[:3], cfg.max_box_spin),
                              (phi._nq + vi[3:], cfg.max_box_speed)):
                w = value[rows]
                speed = np.linalg.norm(w)
                if speed > cap:
                    P = (np.eye(3) - np.outer(w, w) / speed**2) * cap / speed
                    grad[rows] = P @ grad[rows]
        return InitializeAutoDiff(capped, grad).ravel()

    def _force_gradient(self, m: int) -> np.ndarray:
        """d f / d seeds (nf x m) of `Phi.contact_forces` for the current AutoDiffXd state:
        d|F| = F^T dF / |F| per pair, the shelf's share only where it exceeds the allowance."""
        phi = self.phi
        rows = []
        for id_a, id_b, force in contact_pairs(
                self.plant.get_contact_results_output_port().Eval(self.context)):
            F, dF = ExtractValue(force).ravel(), _gradient(force, m)
            magnitude = float(np.linalg.norm(F))
            dmag = F @ dF / magnitude if magnitude > 0 else np.zeros(m)
            rows.append((id_a, id_b, np.concatenate([[magnitude], dmag])))
        f, shelf = phi.sum_by_node(rows, 1 + m)
        pressed = shelf[:, 0] > phi._shelf_allowance
        return f[:, 1:] + np.where(pressed[:, None], shelf[:, 1:], 0.0)

    def _read_jacobian(self, S: np.ndarray) -> np.ndarray:
        phi, layout, m = self.phi, self.phi.layout, S.shape[1]
        q_ad, v_ad = self.plant.GetPositions(self.context), self.plant.GetVelocities(self.context)
        q, Gq = ExtractValue(q_ad).ravel(), _gradient(q_ad, m)
        Gv = _gradient(v_ad, m)
        J = np.zeros((layout.ndx, m))
        J[:ARM_DIM] = S[layout.ndx:]  # the kinematic arm ends at u: d x_arm' = du
        for i in range(layout.num_boxes):
            r = ARM_DIM + BOX_TANGENT * i
            qi, vi = phi._box_q[i], phi._box_v[i]
            quat = q[qi[:4]]
            norm = np.linalg.norm(quat)
            J[r:r + 3] = 4.0 * quaternion_tangent_basis(quat / norm).T @ Gq[qi[:4]] / norm
            J[r + 3:r + 6] = Gq[qi[4:]]
            J[r + 6:r + 12] = Gv[vi]
        return J


def _gradient(values: np.ndarray, m: int) -> np.ndarray:
    """ExtractGradient as (len(values), m): Drake gives (n, 0) for values without derivatives."""
    grad = ExtractGradient(np.asarray(values).reshape(-1))
    return grad if grad.shape[1] == m else np.zeros((grad.shape[0], m))
