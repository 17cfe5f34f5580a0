"""phi's Jacobians A_t = dphi/dx and B_t = dphi/du by finite differences (Sec. V), made fast
enough for iLQR. The step is ``DynamicsConfig.fd_step`` (1e-6 as in the paper; the config's
comment gives the measured trade-off against 1e-5), forward or central (``fd_scheme``).

Brute force perturbs every column of [x, u] (ndx + nu + 1 phi evaluations per knot). Here:

1. Interaction graph. Every traced step records which bodies (the arm, each kept box) came
   within ``interaction_margin`` of each other at the start of some sub-step; bodies in
   different connected components cannot affect each other within the knot.
2. Known blocks. The arm is kinematic, so its rows are exact (0 in A, I in B); when the arm
   touches nothing its columns move nothing else, so they cost no evaluation. Boxes the arm
   does not reach (a component of boxes only) whose states are all the same (within
   ``known_block_tolerance``) as at an earlier knot reuse that knot's Jacobian block: resting
   boxes, alone or leaning on each other, most boxes at most knots.
3. Colouring. The columns still needed are grouped so that each group perturbs at most one
   column per component (Curtis-Powell-Reid: no row sees two perturbed columns); one phi
   evaluation per group, so a knot costs as many evaluations as its largest component has
   columns, not ndx + nu (`colouring`).
4. Parallel workers. Groups are evaluated in ``workers`` spawned processes that each build their
   plant and context once per phi (`workers`; tasks carry only the spec and numpy
   arrays).
5. AutoDiffXd. With ``derivative_method`` "autodiff" (or "hybrid", at knots with at least
   ``autodiff_min_groups`` groups) a knot's groups are not finite differences but the
   directions seeded into one AutoDiffXd step (`autodiff.AutoDiffPhi.directional`):
   exact, and cheaper where the arm pushes several boxes. The colouring and known blocks are the
   same; a group's column of the result is J times the sum of its unit columns either way.
6. Stride. With ``derivative_stride`` k > 1 only every k-th knot (and the last) is
   differentiated; A and B are interpolated linearly (in tangent coordinates) between them.

Jacobians live in tangent coordinates (`state.StateLayout`: rotations as rotation vectors
in W); `PhiDynamics.linearize` maps them to state coordinates (quaternions) for a solver that
differences states plainly, `PhiDynamics.linearize_tangent` returns them as they are.
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from dataclasses import dataclass, field, replace

import numpy as np

from drake_clutter.common.config import Config, check_config
from drake_clutter.phi.autodiff import AutoDiffPhi
from drake_clutter.phi.colouring import (
    colour_groups,
    components,
    group_autodiff,
    group_differences,
    node_columns,
    node_output_rows,
    node_rows,
)
from drake_clutter.phi.dynamics import ARM_NODE, PhiSpec
from drake_clutter.phi.engines import build_phi
from drake_clutter.phi.state import ARM_DIM, NU
from drake_clutter.phi.workers import WorkerPool


@dataclass
class LinearizeStats:
    """What the last `PhiDynamics.linearize` did."""

    knots: int = 0
    differentiated_knots: int = 0
    evaluations: list[int] = field(default_factory=list)  # phi evaluations per knot
    known_boxes: int = 0  # boxes-only component blocks reused from earlier knots
    autodiff_knots: int = 0  # knots differentiated by AutoDiffXd (their groups are seed
    # directions of one AutoDiffXd step, not phi evaluations)
    traced: int = 0  # knots whose nominal step had to be traced again
    autodiff_fallbacks: int = 0  # AutoDiffXd knots with non-finite groups, differenced instead
    failed_evaluations: int = 0
    seconds: float = 0.0

    @property
    def mean_evaluations(self) -> float:
        """Mean phi evaluations per differentiated knot, the nominal step included."""
        return float(np.mean(self.evaluations)) if self.evaluations else 0.0


@dataclass
class _KnotWork:
    t: int
    x: np.ndarray
    u: np.ndarray
    nominal: tuple[np.ndarray, np.ndarray]  # phi's (x', f) at (x, u)
    fd_components: list[list[int]]
    groups: list[list[int]]
    known: dict[tuple, np.ndarray]  # boxes-only component -> block from an earlier call
    copies: dict[tuple, int] = field(default_factory=dict)  # component -> earlier knot t whose
    # block (differentiated in this call) it reuses


class PhiDynamics:
    """phi for iLQR (`ilqr.Dynamics`): ``step(t, x, u)``, ``rollout``, ``linearize``, and the
    contact forces of each step with their Jacobians (``step_forces``, ``linearize_forces``).

    Owns an in-process `Phi` for steps and, with ``config.workers`` > 0, uses a `WorkerPool`
    (its own, or a shared one passed in) for derivatives. Call `close` (or use ``with``) to stop
    an owned pool. Derivatives are taken of ``spec``'s phi at the states its rollouts reach; the
    interaction graph comes from those rollouts.
    """

    def __init__(self, spec: PhiSpec, pool: WorkerPool | None = None):
        check_config(Config(world=spec.world, dynamics=spec.config))
        self.spec = spec
        self.config = spec.config
        self.layout = spec.layout
        self.phi = build_phi(spec)
        self._own_pool = pool is None and self.config.workers > 0
        self.pool = WorkerPool(self.config.workers) if self._own_pool else pool
        self._steps: OrderedDict = OrderedDict()
        self._known: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}  # boxes-only component
        # -> (its box states, its output-row block) from an earlier knot or call
        self._last: tuple | None = None  # (key of xs, us; full Jacobians; forces) of the last
        # linearisation
        self.stats = LinearizeStats()
        self._autodiff: AutoDiffPhi | None = None  # in-process, built on first serial use
        self.autodiff_fallbacks = 0  # knots differenced because AutoDiffXd failed, all calls

    @property
    def num_forces(self) -> int:
        """Length of the contact-force vector f (1 + kept boxes; see `step_forces`)."""
        return self.phi.num_forces

    # -- dynamics

    def step(self, t: int, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """phi(x, u) (``t`` is unused: phi is time-invariant); remembered for linearize."""
        return self._traced(x, u)[0].copy()

    def step_forces(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The contact forces f (N, shape (1 + n,)) of phi's step from (x, u): entry 0 the
        arm, entry i + 1 kept box i, each the sum of the contact-force magnitudes between that
        body and every other object (not the shelf), averaged over the knot's sub-steps
        (`dynamics.Phi.contact_forces`). Table I's force(q, x) for c_force."""
        return self._traced(x, u)[2].copy()

    def edges(self, x: np.ndarray, u: np.ndarray) -> set:
        """The interaction edges of phi's step from (x, u) (`dynamics.Phi.step_traced`); a
        step already taken is not taken again."""
        return self._traced(x, u)[1]

    def rollout(self, x0: np.ndarray, us: np.ndarray) -> np.ndarray:
        """States x_0..x_T of controls ``us`` (T, 8) from x0."""
        xs = np.empty((len(us) + 1, self.layout.nx))
        xs[0] = x0
        for t, u in enumerate(us):
            xs[t + 1] = self.step(t, xs[t], u)
        return xs

    def _key(self, x, u) -> tuple[bytes, bytes]:
        return np.asarray(x, dtype=float).tobytes(), np.asarray(u, dtype=float).tobytes()

    def _traced(self, x, u) -> tuple[np.ndarray, set, np.ndarray]:
        key = self._key(x, u)
        hit = self._steps.get(key)
        if hit is None:
            hit = self._remember(key, self.phi.step_full(x, u))
        self._steps.move_to_end(key)
        return hit

    def remember_steps(self, records) -> None:
        """Takes in steps run elsewhere, ((x, u), `Phi.step_full` result) pairs from another
        process's Phi of this spec, as if stepped here (for the forces and `linearize`)."""
        for (x, u), result in records:
            self._remember(self._key(x, u), result)

    def _remember(self, key, result) -> tuple[np.ndarray, set, np.ndarray]:
        self._steps[key] = result
        while len(self._steps) > self.config.step_cache_size:
            self._steps.popitem(last=False)
        return result

    # -- derivatives

    def linearize(self, xs: np.ndarray, us: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A (T, nx, nx), B (T, nx, nu) in state coordinates (quaternions): A_t = G(x_{t+1})
        A~_t G+(x_t), B_t = G(x_{t+1}) B~_t with the tangent Jacobians A~, B~."""
        A_tan, B_tan = self.linearize_tangent(xs, us)
        A = np.empty((len(us), self.layout.nx, self.layout.nx))
        B = np.empty((len(us), self.layout.nx, NU))
        for t in range(len(us)):
            G_next = self.layout.tangent_to_state(xs[t + 1])
            A[t] = G_next @ A_tan[t] @ self.layout.state_to_tangent(xs[t])
            B[t] = G_next @ B_tan[t]
        return A, B

    def linearize_tangent(self, xs: np.ndarray, us: np.ndarray, stride: int | None = None):
        """A~ (T, ndx, ndx), B~ (T, ndx, nu) in tangent coordinates about (xs, us). The same
        finite differences give the contact forces' Jacobians: `linearize_forces`. ``stride``
        overrides ``config.derivative_stride`` (every k-th knot differentiated)."""
        J = self._linearize_full(xs, us, stride)
        ndx = self.layout.ndx
        return J[:, :ndx, :ndx].copy(), J[:, :ndx, ndx:].copy()

    def linearize_forces(self, xs: np.ndarray, us: np.ndarray, stride: int | None = None):
        """Contact forces and their Jacobians about (xs, us): f (T, nf), Fx (T, nf, ndx),
        Fu (T, nf, nu), nf = 1 + kept boxes. Row 0 is the arm's force, row i + 1 kept box i's
        (the layout of `step_forces`); columns are tangent coordinates of x_t and u_t, as in
        `linearize_tangent`. Free after `linearize_tangent` on the same (xs, us): both come
        from one set of finite differences (a row is differenced with the columns of its
        body's interaction component, so the colouring holds for it too)."""
        J = self._linearize_full(xs, us, stride)
        ndx = self.layout.ndx
        f = np.array([self._traced(xs[t], us[t])[2] for t in range(len(J))])
        return f, J[:, ndx:, :ndx].copy(), J[:, ndx:, ndx:].copy()

    def _linearize_full(self, xs: np.ndarray, us: np.ndarray,
                        stride: int | None = None) -> np.ndarray:
        """Jacobians (T, ndx + nf, ndx + nu) of phi's output [x', f] w.r.t. [dx, du]."""
        us = np.atleast_2d(np.asarray(us, dtype=float))
        xs = np.asarray(xs, dtype=float)
        stride = self.config.derivative_stride if stride is None else stride
        key = (xs[:len(us)].tobytes(), us.tobytes(), len(us), stride)
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        tic = time.perf_counter()
        T = len(us)
        knots = differentiated_knots(T, stride)
        self.stats = LinearizeStats(knots=T)
        self._trace_missing(xs, us, range(T))
        self.stats.differentiated_knots = len(knots)
        pending: dict[tuple, list[tuple[np.ndarray, int]]] = {}
        work = [self._plan(t, xs[t], us[t], pending) for t in knots]
        results = self._evaluate(work)
        J = np.zeros((T, self.layout.ndx + self.num_forces, self.layout.ndx + NU))
        for w, D in zip(work, results, strict=True):  # in knot order: copies come from earlier
            for comp, source in w.copies.items():
                w.known[comp] = J[source][np.ix_(self._out_rows(comp), self._rows(comp))]
            self._assemble(w, D, J[w.t])
            if self._uses_autodiff(w):
                self.stats.autodiff_knots += 1
            else:
                self.stats.evaluations.append(1 + len(w.groups) * self._evals_per_group())
        interpolate_between(J, np.zeros((T, 0, 0)), knots)
        self.stats.seconds = time.perf_counter() - tic
        self._last = (key, J)
        return J

    def _evals_per_group(self) -> int:
        return 2 if self.config.fd_scheme == "central" else 1

    def _trace_missing(self, xs, us, knots) -> None:
        missing = [t for t in knots if self._key(xs[t], us[t]) not in self._steps]
        self.stats.traced = len(missing)
        if not missing:
            return
        if self.pool is None:
            results = [self.phi.step_full(xs[t], us[t]) for t in missing]
        else:
            key = self.spec.key
            results = self.pool.map([("trace", key, self.spec, xs[t], us[t]) for t in missing])
        for t, result in zip(missing, results, strict=True):
            self._remember(self._key(xs[t], us[t]), result)

    def _rows(self, comp) -> np.ndarray:
        return np.concatenate([node_rows(self.layout, n) for n in comp])

    def _out_rows(self, comp) -> np.ndarray:
        return np.concatenate([node_output_rows(self.layout, n) for n in comp])

    def _plan(self, t: int, x, u, pending: dict) -> _KnotWork:
        """What knot t needs: components to difference, colour groups, reusable blocks.

        A component of boxes only (the arm touches none of them) whose states all lie within
        ``known_block_tolerance`` of an earlier knot's reuses that knot's block: from an
        earlier call (``known``) or from a knot differenced in this call (``copies``, found in
        ``pending``: component -> [(states, knot)])."""
        x_next, edges, f = self._steps[self._key(x, u)]
        fd, known, copies = [], {}, {}
        tolerance = self.config.known_block_tolerance
        for comp in components(self.layout.num_boxes + 1, edges):
            if comp == [ARM_NODE]:
                continue  # kinematic arm touching nothing: its block is exact
            if ARM_NODE not in comp:
                key = tuple(comp)
                states = self.layout.boxes(x)[[n - 1 for n in comp]]
                hit = self._known.get(key)
                if hit is not None and _close(hit[0], states, tolerance):
                    known[key] = hit[1]
                    continue
                source = next((k for s, k in pending.get(key, ()) if _close(s, states, tolerance)),
                              None)
                if source is not None:
                    copies[key] = source
                    continue
                pending.setdefault(key, []).append((states, t))
            fd.append(comp)
        columns = [sum((node_columns(self.layout, n) for n in comp), []) for comp in fd]
        self.stats.known_boxes += len(known) + len(copies)
        return _KnotWork(t, x, u, (x_next, f), fd, colour_groups(columns), known, copies)

    def _uses_autodiff(self, w: _KnotWork) -> bool:
        """Whether knot work ``w`` is differentiated by AutoDiffXd (``derivative_method``)."""
        method = self.config.derivative_method
        if (not w.groups or method == "fd" or self.config.contact_model == "point"
                or self.config.engine != "drake"):
            return False
        return method == "autodiff" or len(w.groups) >= self.config.autodiff_min_groups

    def _evaluate(self, work: list[_KnotWork]) -> list[np.ndarray]:
        """Directional derivatives per knot, (groups, ndx + nf) each: difference quotients or
        AutoDiffXd (`_uses_autodiff`). Groups whose AutoDiffXd result is not finite are
        differenced instead (``stats.autodiff_fallbacks``): Drake's AutoDiffXd SAP step can
        return finite values with NaN gradients (fig8's resting box rows at some knots: 3 of
        29 knots of the first sphere-stage linearisation, measured), and iLQR would otherwise
        see zeros there."""
        results = self._evaluate_with(work, self._uses_autodiff)
        retry = {}
        for i, (w, D) in enumerate(zip(work, results, strict=True)):
            bad = np.flatnonzero(~np.all(np.isfinite(D), axis=1))
            if len(bad) and self._uses_autodiff(w):
                retry[i] = bad
        if retry:
            self.stats.autodiff_fallbacks += len(retry)
            self.autodiff_fallbacks += len(retry)
            again = [replace(work[i], groups=[work[i].groups[g] for g in rows])
                     for i, rows in retry.items()]
            for (i, rows), D in zip(retry.items(), self._evaluate_with(again, lambda w: False),
                                    strict=True):
                results[i][rows] = D
        return results

    def _evaluate_with(self, work: list[_KnotWork], autodiff) -> list[np.ndarray]:
        """`_evaluate`'s first pass: AutoDiffXd at the knots where ``autodiff(w)``, finite
        differences elsewhere; split into pool tasks (one per AutoDiffXd knot)."""
        h, scheme = self.config.fd_step, self.config.fd_scheme
        if self.pool is None:
            return [self._serial(w, h, scheme, autodiff(w)) for w in work]
        fd_groups = sum(len(w.groups) for w in work if not autodiff(w))
        chunk = max(1, math.ceil(fd_groups / (16 * self.pool.workers)))  # small: balance
        tasks, owners = [], []
        for i, w in enumerate(work):
            if autodiff(w):
                tasks.append(("autodiff", self.spec.key, self.spec, w.x, w.u, w.groups))
                owners.append(i)
                continue
            for start in range(0, len(w.groups), chunk):
                tasks.append(("groups", self.spec.key, self.spec, w.x, w.u, w.nominal,
                              w.groups[start:start + chunk], h, scheme))
                owners.append(i)
        parts: list[list[np.ndarray]] = [[] for _ in work]
        for i, result in zip(owners, self.pool.map(tasks), strict=True):
            parts[i].append(result)
        width = self.layout.ndx + self.num_forces
        return [np.vstack(p) if p else np.zeros((0, width)) for p in parts]

    def _serial(self, w: _KnotWork, h: float, scheme: str, autodiff: bool) -> np.ndarray:
        if not autodiff:
            return group_differences(self.phi, w.x, w.u, w.nominal, w.groups, h, scheme)
        if self._autodiff is None:
            self._autodiff = AutoDiffPhi(self.phi)
        return group_autodiff(self._autodiff, w.x, w.u, w.groups)

    def _assemble(self, w: _KnotWork, D: np.ndarray, J: np.ndarray) -> None:
        """Scatters a knot's difference quotients into its output Jacobian J (ndx + nf,
        ndx + nu) and refreshes known blocks."""
        layout, ndx = self.layout, self.layout.ndx
        self.stats.failed_evaluations += int(np.sum(~np.all(np.isfinite(D), axis=1)))
        J[:] = 0.0
        for comp in w.fd_components:
            rows = self._out_rows(comp)
            for g, col in enumerate(sum((node_columns(layout, n) for n in comp), [])):
                J[rows, col] = D[g, rows]
        for comp, block in w.known.items():
            J[np.ix_(self._out_rows(comp), self._rows(comp))] = block
        for comp in w.fd_components:
            if ARM_NODE not in comp:
                block = J[np.ix_(self._out_rows(comp), self._rows(comp))]
                if np.all(np.isfinite(block)):
                    states = layout.boxes(w.x)[[n - 1 for n in comp]].copy()
                    self._known[tuple(comp)] = (states, block.copy())
        J[:ARM_DIM] = 0.0  # the kinematic arm: x_arm' = u exactly
        J[:ARM_DIM, ndx:ndx + NU] = np.eye(NU)

    def close(self) -> None:
        """Stops an owned worker pool."""
        if self._own_pool and self.pool is not None:
            self.pool.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _close(a: np.ndarray, b: np.ndarray, tolerance: float) -> bool:
    return bool(np.max(np.abs(a - b)) <= tolerance)


def box_speeds(layout, x: np.ndarray) -> np.ndarray:
    """Each kept box's |v| + 0.1 m x |w| in state x (m/s; W frame): how fast a box still
    moves."""
    boxes = layout.boxes(x)
    return np.linalg.norm(boxes[:, 10:13], axis=1) + 0.1 * np.linalg.norm(boxes[:, 7:10], axis=1)


def differentiated_knots(num_knots: int, stride: int) -> list[int]:
    """Knots 0, k, 2k, ... and the last one."""
    if stride < 1:
        raise ValueError(f"derivative_stride must be at least 1, got {stride}")
    return sorted(set(range(0, num_knots, stride)) | {num_knots - 1}) if num_knots else []


def interpolate_between(A: np.ndarray, B: np.ndarray, knots: list[int]) -> None:
    """Fills the knots between differentiated ones by linear interpolation, in place."""
    for k0, k1 in zip(knots[:-1], knots[1:], strict=True):
        for t in range(k0 + 1, k1):
            s = (t - k0) / (k1 - k0)
            A[t] = (1 - s) * A[k0] + s * A[k1]
            B[t] = (1 - s) * B[k0] + s * B[k1]
