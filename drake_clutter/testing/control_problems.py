"""Small control problems with known answers for the solvers' tests: a linear system with a
quadratic cost (LQR, solved exactly by batch least squares) and a damped pendulum swing-up."""

from __future__ import annotations

import numpy as np

from drake_clutter.solvers.ilqr import Expansion


class LinearDynamics:
    """x_{t+1} = A x_t + B u_t."""

    def __init__(self, A, B):
        self.A, self.B = A, B

    def step(self, t, x, u):
        return self.A @ x + self.B @ u

    def linearize(self, xs, us):
        T = len(us)
        return np.repeat(self.A[None], T, 0), np.repeat(self.B[None], T, 0)


class QuadraticCost:
    """sum_t 1/2 x'Qx + 1/2 u'Ru + 1/2 x_T' Qf x_T."""

    def __init__(self, Q, R, Qf):
        self.Q, self.R, self.Qf = Q, R, Qf

    def terms(self, xs, us):
        state = 0.5 * np.einsum("ti,ij,tj->", xs[:-1], self.Q, xs[:-1])
        control = 0.5 * np.einsum("ti,ij,tj->", us, self.R, us)
        return {"state": state, "control": control, "terminal": 0.5 * xs[-1] @ self.Qf @ xs[-1]}

    def quadratize(self, xs, us):
        T = len(us)
        return Expansion(lx=xs[:-1] @ self.Q, lu=us @ self.R,
                         lxx=np.repeat(self.Q[None], T, 0), luu=np.repeat(self.R[None], T, 0),
                         lux=np.zeros((T, us.shape[1], xs.shape[1])), vx=self.Qf @ xs[-1],
                         vxx=self.Qf)


def lqr_problem(seed=0, T=25):
    """A random stable-ish LQR problem: (A, B, Q, R, Qf, x0, T), 4 states, 2 controls."""
    rng = np.random.default_rng(seed)
    nx, nu = 4, 2
    A = np.eye(nx) + 0.1 * rng.standard_normal((nx, nx))
    B = 0.1 * rng.standard_normal((nx, nu))
    Q = np.diag(rng.uniform(0.5, 2.0, nx))
    R = np.diag(rng.uniform(0.1, 1.0, nu))
    Qf = 10 * np.eye(nx)
    x0 = rng.standard_normal(nx)
    return A, B, Q, R, Qf, x0, T


class Pendulum:
    """Damped pendulum, x = (angle, rate), u = torque; explicit Euler, dt = 0.05."""

    dt = 0.05

    def step(self, t, x, u):
        th, w = x
        return np.array([th + self.dt * w, w + self.dt * (-9.81 * np.sin(th) - 0.1 * w + u[0])])

    def linearize(self, xs, us):
        T = len(us)
        A = np.zeros((T, 2, 2))
        A[:, 0, 0] = 1.0
        A[:, 0, 1] = self.dt
        A[:, 1, 0] = -self.dt * 9.81 * np.cos(xs[:-1, 0])
        A[:, 1, 1] = 1 - 0.1 * self.dt
        B = np.zeros((T, 2, 1))
        B[:, 1, 0] = self.dt
        return A, B


class SwingUpCost:
    """Effort 0.01 |u|^2 / 2 per knot and 100 |x_T - (pi, 0)|^2 / 2 at the end."""

    goal = np.array([np.pi, 0.0])

    def terms(self, xs, us):
        return {"effort": 0.5 * 0.01 * float(np.sum(us ** 2)),
                "terminal": 0.5 * 100.0 * float(np.sum((xs[-1] - self.goal) ** 2))}

    def quadratize(self, xs, us):
        T = len(us)
        return Expansion(lx=np.zeros((T, 2)), lu=0.01 * us, lxx=np.zeros((T, 2, 2)),
                         luu=np.full((T, 1, 1), 0.01), lux=np.zeros((T, 1, 2)),
                         vx=100.0 * (xs[-1] - self.goal), vxx=100.0 * np.eye(2))


def stacked_lqr(A, B, Q, R, Qf, T):
    """The LQR problem over a whole horizon: (Sx, Su, Qbar, Rbar) with the stacked states
    x = Sx x0 + Su U and the objective 1/2 x' Qbar x + 1/2 U' Rbar U (batch least squares)."""
    nx, nu = B.shape
    Sx = np.zeros(((T + 1) * nx, nx))
    Su = np.zeros(((T + 1) * nx, T * nu))
    for t in range(T + 1):
        Sx[t * nx:(t + 1) * nx] = np.linalg.matrix_power(A, t)
        for s in range(t):
            Su[t * nx:(t + 1) * nx, s * nu:(s + 1) * nu] = np.linalg.matrix_power(A, t - 1 - s) @ B
    Qbar = np.kron(np.eye(T + 1), Q)
    Qbar[-nx:, -nx:] = Qf
    return Sx, Su, Qbar, np.kron(np.eye(T), R)
