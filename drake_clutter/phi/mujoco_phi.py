"""phi in MuJoCo (``dynamics.engine: mujoco``): the same model as the Drake `dynamics.Phi`
in the paper's own engine (`mujoco_model`), with the same state, controls and outputs.

One step advances one knot interval in `mujoco_model.substeps` MuJoCo steps, run in C in
runs of ``mujoco_sample_steps`` (20 ms by default, the Drake phi's sub-step). Before each run
the arm's joints are set on the knot's straight joint-space line with its constant velocity
(u - x_arm) / knot_time; their large armature keeps them on it within the run (kinematic; after
the last step the arm's state is u exactly); the boxes start at their state. After each run
phi reads the contacts of its last step (forces, edges, jam, each standing for the run's
steps) and caps every box's speed as the Drake phi does (`dynamics.cap_box_speeds`). Every
knot starts from ``mj_resetData`` (no warm start kept between calls), so the same (x, u)
gives the same bits. The judge in phi does not step functionally: `MujocoPhi.keep_world`
settles the boxes once and `kept_knots` runs each path from a copy of that world through its
knots with no reset (the same runs, arm and readings), so MuJoCo's sleeping islands
(``mujoco_sleep``) keep the resting boxes out of the step.

Outputs, as `dynamics.Phi`'s: the next state; the interaction edges (pairs of nodes whose
geometries touch at the end of a run, or lie within ``interaction_margin`` at the knot's start
or its end, as the Drake phi traces them at its sub-steps); the contact forces per node of
Table I (each contact's |f|, normal and friction together, averaged over the knot's runs; a
kept box's shelf contacts beyond ``shelf_force_allowance`` x its weight) and the shelf forces;
the jam measure (`jam`), read from MuJoCo's contacts.

Contact: MuJoCo's soft contact with an impedance that starts near zero at touch
(``mujoco_impedance_min``) and a solver run to ``mujoco_solver_tolerance``: with MuJoCo's
defaults (impedance 0.9 at touch, tolerance 1e-8) phi jumps where a contact begins or the
solver stops early, and its finite differences are noise (docs/phi.md).

A simulation failure (MuJoCo's bad-acceleration reset, or a state beyond
``divergence_limit``) is not raised: the step returns a state full of NaN and counts it in
``failures``.

Frames: W. MuJoCo's free joint has (p_WB, quaternion wxyz) positions and (v_WB in W, w in the
body frame) velocities; phi's state has w_WB in W: the two are converted here.
"""

from __future__ import annotations

import copy
import math

import mujoco
import numpy as np

from drake_clutter.phi.dynamics import ARM_NODE, PhiBase, PhiSpec, cap_box_speeds, reach
from drake_clutter.phi.jam import (
    ACTOR,
    MAX_CHAIN,
    MIN_FORCE,
    Contact,
    approach_speeds,
    proved_free,
)
from drake_clutter.phi.mujoco_model import (
    ModelBox,
    arm_actor,
    box_geom,
    model_xml,
    scene_pair_friction,
    substeps,
)
from drake_clutter.phi.state import ARM_DIM, scene_box_states
from drake_clutter.trajectory import robot_positions

STATIC = -(10 ** 9)  # node of the shelf's geometry (no interaction node)
SQRT3 = math.sqrt(3.0)
_BAD_ACCELERATION = int(mujoco.mjtWarning.mjWARN_BADQACC)
# MuJoCo's warnings after which it resets the data (a bad position, speed or acceleration)
_RESETS = [int(mujoco.mjtWarning.mjWARN_BADQPOS), int(mujoco.mjtWarning.mjWARN_BADQVEL),
           _BAD_ACCELERATION]


def as_slice(index: np.ndarray):
    """The flat ``index`` (ints) as a slice where it counts up by one from its first entry
    (a view instead of a gather), else ``index`` itself."""
    index = np.asarray(index, dtype=int).ravel()
    if index.size == 0 or not np.array_equal(index, index[0] + np.arange(index.size)):
        return index
    return slice(int(index[0]), int(index[0]) + index.size)


def rotation_matrices(quat_wxyz: np.ndarray) -> np.ndarray:
    """R (n, 3, 3) of unit quaternion rows (w, x, y, z)."""
    w, x, y, z = np.asarray(quat_wxyz, dtype=float).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def contact_magnitudes(model, data) -> np.ndarray:
    """|f| (N) of each of ``data``'s contacts (normal and friction together; 0 for a
    contact within the margin that does not act), decoded from MuJoCo's pyramidal cone forces
    as ``mj_contactForce`` does, for all contacts at once."""
    n = data.ncon
    if n == 0:
        return np.zeros(0)
    address = data.contact.efc_address[:n]
    active = address >= 0
    if not active.any():
        return np.zeros(n)
    rows = np.where(active, address, 0)[:, None] + np.arange(4)
    f = data.efc_force[rows]
    mu = data.contact.friction[:n, 0]
    normal = f.sum(axis=1)
    t1, t2 = mu * (f[:, 0] - f[:, 1]), mu * (f[:, 2] - f[:, 3])
    return np.where(active, np.sqrt(normal ** 2 + t1 ** 2 + t2 ** 2), 0.0)


def _jam_node(node: int):
    """An interaction node as `jam` names it: ACTOR, kept box index, None (static)."""
    if node == ARM_NODE:
        return ACTOR
    return node - 1 if node > ARM_NODE else None


def jam_contacts(model, data, nodes: np.ndarray) -> list[Contact]:
    """The data's contacts that carry a force (`jam.MIN_FORCE`) as `jam.Contact`s, each
    listed from the side of every kept box it touches that the arm reaches through a chain of
    touching kept boxes (the only contacts `jam.approach_speeds` reads); ``nodes`` maps
    geometry ids to interaction nodes (ARM_NODE, box i + 1, frozen boxes negative, STATIC)."""
    n = data.ncon
    if n == 0 or not np.any(nodes[data.contact.geom[:n]] == ARM_NODE):
        return []  # the arm touches nothing: no box can be blocked under it
    magnitude = contact_magnitudes(model, data)
    acting = np.flatnonzero(magnitude >= MIN_FORCE)
    pairs = nodes[data.contact.geom[acting]] if acting.size else np.zeros((0, 2), int)
    reached = _pushed_boxes(pairs)
    if not reached:
        return []  # the arm pushes no kept box: no box can be blocked under it
    lookup = np.zeros(max(reached) + 1, dtype=bool)  # reached nodes are kept boxes, > 0
    lookup[list(reached)] = True
    hit = lookup[np.clip(pairs, 0, len(lookup) - 1)] & (pairs > ARM_NODE)
    rows = (pairs[:, 0] != pairs[:, 1]) & (hit[:, 0] | hit[:, 1])
    i = acting[rows]
    contact = data.contact  # read in bulk: each attribute access builds a view
    geoms, normals = contact.geom[i].tolist(), contact.frame[i, :3]  # from geom1 into geom2
    points, mus = contact.pos[i], contact.friction[i, 0].tolist()
    out = []
    for k, ((m1, m2), (g1, g2), (hit1, hit2)) in enumerate(
            zip(pairs[rows].tolist(), geoms, hit[rows].tolist(), strict=True)):
        n1, n2 = _jam_node(m1), _jam_node(m2)
        if hit2:
            out.append(Contact(n2, n1, normals[k].copy(), points[k].copy(), mus[k], g1))
        if hit1:
            out.append(Contact(n1, n2, -normals[k], points[k].copy(), mus[k], g2))
    return out


def _pushed_boxes(pairs: np.ndarray) -> set[int]:
    """The kept boxes' nodes (> ARM_NODE) that the arm touches in the node ``pairs`` (k, 2),
    and those they touch in turn, and so on."""
    box = pairs > ARM_NODE
    arm = pairs == ARM_NODE
    reached = set(pairs[arm[:, 0] & box[:, 1], 1].tolist()) | set(
        pairs[arm[:, 1] & box[:, 0], 0].tolist())
    if not reached:
        return reached
    links = {}
    for a, b in pairs[box[:, 0] & box[:, 1]].tolist():
        if a != b:
            links.setdefault(a, set()).add(b)
            links.setdefault(b, set()).add(a)
    return reach(reached, links)


def approaching(model, data, nodes: np.ndarray, v_commanded: np.ndarray) -> list[tuple]:
    """The data's contacts where the arm, at the generalized velocity ``v_commanded``, moves
    into a kept box (its material point's W velocity along the contact normal from the arm
    into the box above 0): (contact row, the box's node, that normal) each. Without one,
    `jam.approach_speeds` reads nothing, and `jam_contacts` need not be built. ``nodes`` maps
    geometry ids to interaction nodes."""
    n = data.ncon
    if n == 0 or not np.any(v_commanded):
        return []
    contact = data.contact  # read in bulk: each attribute access builds a view
    geom = contact.geom[:n]
    pair = nodes[geom]
    first = (pair[:, 0] == ARM_NODE) & (pair[:, 1] > ARM_NODE)
    rows = np.flatnonzero(first | ((pair[:, 1] == ARM_NODE) & (pair[:, 0] > ARM_NODE)))
    if rows.size == 0:
        return []
    sign = np.where(first[rows], 1.0, -1.0)[:, None]
    pushes = contact.frame[rows, :3] * sign  # arm into box
    points = contact.pos[rows]
    jacobian = np.zeros((3, model.nv))
    out = []
    for k, i in enumerate(rows.tolist()):
        arm_side, box_side = (0, 1) if first[i] else (1, 0)
        mujoco.mj_jac(model, data, jacobian, None, points[k],
                      int(model.geom_bodyid[geom[i, arm_side]]))
        if float((jacobian @ v_commanded) @ pushes[k]) > 0.0:
            out.append((i, int(pair[i, box_side]), pushes[k]))
    return out


def pushes_free(model, data, nodes: np.ndarray, pushes: list[tuple]) -> bool:
    """Whether no box is blocked under the ``pushes`` (`approaching`), proved from the
    contact normals alone (`_Touching.free`) at each push whose contact carries a force
    (`MIN_FORCE`). Where this says yes, `jam.approach_speeds` of `jam_contacts` reads no box
    (the same answer, without building the contacts); a no proves nothing."""
    magnitude = contact_magnitudes(model, data)
    acting = np.flatnonzero(magnitude >= MIN_FORCE)
    touching = _Touching(nodes[data.contact.geom[acting]].tolist(),
                         data.contact.frame[acting, :3].tolist(),
                         data.contact.friction[acting, 0].tolist())
    return all(magnitude[i] < MIN_FORCE or touching.free(box, tuple(push.tolist()), (box,))
               for i, box, push in pushes)


class _Touching:
    """The contacts that carry a force, by the kept box they touch: [(normal into it,
    the other side's node, Coulomb coefficient)], the arm's left out; plain floats (a step
    has a few dozen contacts: arrays would cost more than they save)."""

    def __init__(self, pairs: list, frames: list, mus: list):
        self.of: dict = {}
        for (n1, n2), (x, y, z), mu in zip(pairs, frames, mus, strict=True):
            if n1 == n2 or ARM_NODE in (n1, n2):
                continue
            if n2 > ARM_NODE:  # the frame's normal is from geom1 into geom2
                self.of.setdefault(n2, []).append(((x, y, z), n1, mu))
            if n1 > ARM_NODE:
                self.of.setdefault(n1, []).append(((-x, -y, -z), n2, mu))
        self._answers: dict = {}

    def free(self, node: int, push: tuple, chain: tuple) -> bool:
        """A proof that the box ``node`` pushed along the unit ``push`` is not `jam.blocked`
        (the same chain rule): its static contacts' cones cannot hold the push
        (`jam.proved_free`), and every kept box it presses against the push (not back along
        ``chain``, at most `jam.MAX_CHAIN` boxes) is free in turn under the push it passes
        on."""
        key = (node, push, chain)
        if key not in self._answers:
            self._answers[key] = self._free(node, push, chain)
        return self._answers[key]

    def _free(self, node: int, push: tuple, chain: tuple) -> bool:
        touching = self.of.get(node, ())
        static = [(n, mu) for n, other, mu in touching if other < ARM_NODE]
        if static and not proved_free((-push[0], -push[1], -push[2]), [n for n, _ in static],
                                      [mu for _, mu in static]):
            return False
        if len(chain) >= MAX_CHAIN:
            return True
        return all(other in chain or other < ARM_NODE
                   or n[0] * push[0] + n[1] * push[1] + n[2] * push[2] >= 0.0
                   or self.free(other, (-n[0], -n[1], -n[2]), chain + (other,))
                   for n, other, _ in touching)


def commanded_point_velocity(model, data, v_commanded: np.ndarray):
    """contact -> the W velocity (m/s) of the material point at ``contact.point`` of the
    body carrying ``contact.geometry_b`` under the generalized velocity ``v_commanded``."""
    jacobian = np.zeros((3, model.nv))

    def velocity(c: Contact) -> np.ndarray:
        mujoco.mj_jac(model, data, jacobian, None, c.point, int(model.geom_bodyid[c.geometry_b]))
        return jacobian @ v_commanded

    return velocity


class MujocoPhi(PhiBase):
    """One phi model in MuJoCo (built once) that steps knots like `dynamics.Phi`."""

    def __init__(self, spec: PhiSpec):
        super().__init__(spec)
        config, scene = spec.config, spec.scene
        rest = scene_box_states(scene)
        frozen = dict(spec.frozen)
        boxes = [ModelBox(n, scene.box(n).size, scene.box(n).mass, tuple(rest[n][:7]), True)
                 for n in self.layout.box_names]
        boxes += [ModelBox(n, scene.box(n).size, scene.box(n).mass, frozen[n], False)
                  for n, _ in spec.frozen]
        actor = arm_actor(scene, spec.variant, config.mujoco_arm_armature)
        self.xml = model_xml(scene.shelf, boxes, actor, scene_pair_friction(scene), config,
                             spec.knot_time, spec.arm_passes)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        self.substeps = substeps(spec.knot_time, config)
        m = self.model
        self._arm_q = np.array([m.joint(j).qposadr[0] for j in actor.joints])
        self._arm_v = np.array([m.joint(j).dofadr[0] for j in actor.joints])
        joints = [m.body(box_geom(n)).jntadr[0] for n in self.layout.box_names]
        self._box_q = np.array([m.jnt_qposadr[j] + np.arange(7) for j in joints],
                               dtype=int).reshape(-1, 7)
        self._box_v = np.array([m.jnt_dofadr[j] + np.arange(6) for j in joints],
                               dtype=int).reshape(-1, 6)
        self._cap_index = self._box_v[:, [3, 4, 5, 0, 1, 2]]  # (w, v) as cap_box_speeds reads
        self._arm_qs, self._arm_vs = as_slice(self._arm_q), as_slice(self._arm_v)
        self._box_qs, self._box_vs = as_slice(self._box_q), as_slice(self._box_v)
        self._nodes = np.full(m.ngeom, STATIC, dtype=np.int64)
        self._nodes[[m.geom(g).id for g in actor.geoms]] = ARM_NODE
        for i, name in enumerate(self.layout.box_names):  # the box and its edge spheres
            self._nodes[m.geom_bodyid == m.body(box_geom(name)).id] = i + 1
        for j, (name, _) in enumerate(spec.frozen):
            self._nodes[m.geom(box_geom(name)).id] = -(j + 1)

    def clone(self) -> MujocoPhi:
        """The same phi with its own MuJoCo data and model copy (`_near_edges` widens the
        model's margins for a moment), to step in another thread: MuJoCo releases the GIL while
        it steps; the same (x, u) gives the same bits in either."""
        twin = copy.copy(self)
        twin.model = copy.copy(self.model)
        twin.data = mujoco.MjData(twin.model)
        twin.failures = 0
        return twin

    # -- state in and out

    def _load(self, x: np.ndarray, q_arm: np.ndarray, v_arm: np.ndarray) -> None:
        """Resets the data to x's boxes and the arm at ``q_arm`` moving at ``v_arm``."""
        d = self.data
        mujoco.mj_resetData(self.model, d)
        boxes = self.layout.boxes(x)
        if len(boxes):
            quats = boxes[:, :4] / np.linalg.norm(boxes[:, :4], axis=1, keepdims=True)
            d.qpos[self._box_q[:, :3]] = boxes[:, 4:7]
            d.qpos[self._box_q[:, 3:]] = quats
            d.qvel[self._box_v[:, :3]] = boxes[:, 10:13]
            d.qvel[self._box_v[:, 3:]] = np.einsum("nji,nj->ni", rotation_matrices(quats),
                                                   boxes[:, 7:10])  # w_B = R^T w_W
        d.qpos[self._arm_q] = q_arm
        d.qvel[self._arm_v] = v_arm

    def _read(self, u: np.ndarray) -> np.ndarray:
        """x now: the arm at u (kinematic), the kept boxes from the data."""
        d = self.data
        quats = d.qpos[self._box_q[:, 3:]]
        w_world = np.einsum("nij,nj->ni", rotation_matrices(
            quats / np.linalg.norm(quats, axis=1, keepdims=True)), d.qvel[self._box_v[:, 3:]])
        boxes = np.concatenate([quats, d.qpos[self._box_q[:, :3]], w_world,
                                d.qvel[self._box_v[:, :3]]], axis=1)
        if len(boxes):
            diverged = ~np.all(np.abs(boxes) <= self.spec.config.divergence_limit, axis=1)
            boxes[diverged] = np.nan
            boxes[:, :4] /= np.linalg.norm(boxes[:, :4], axis=1, keepdims=True)
            boxes[:, :4] *= np.where(boxes[:, :1] < 0, -1.0, 1.0)
        return self.layout.join(np.asarray(u, dtype=float), boxes)

    # -- stepping

    def _step(self, x, u, trace: bool, forces: bool,
              jam: np.ndarray | None = None) -> tuple[np.ndarray, set, np.ndarray]:
        f, shelf = np.zeros(self.num_forces), np.zeros(self.num_forces)
        self.shelf_forces = shelf * np.nan
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(u))):
            self.failures += 1
            return np.full(self.layout.nx, np.nan), set(), f * np.nan
        d, n = self.data, self.substeps
        q_start, q_end = robot_positions(x[:ARM_DIM]), robot_positions(u)
        self._load(x, q_start, (q_end - q_start) / self.spec.knot_time)
        edges = self._near_edges() if trace else set()
        edges |= self._runs(q_start, q_end, trace, jam, (f, shelf) if forces else None)
        x_next = self._read(u)
        if trace:
            d.qpos[self._arm_q] = q_end
            edges |= self._near_edges()
        if d.warning[_BAD_ACCELERATION].number > 0 or not np.all(np.isfinite(x_next)):
            self.failures += 1
            return np.full(self.layout.nx, np.nan), edges, f * np.nan
        if forces:
            self.shelf_forces = shelf / n
        return x_next, edges, f / n

    def _near_edges(self) -> set:
        """Node pairs within ``interaction_margin`` in the data's positions: a collision
        query with the pairs' margin widened for it alone (module docstring of
        `mujoco_model`)."""
        m = self.model
        m.pair_margin[:] = self.spec.config.interaction_margin
        try:
            mujoco.mj_kinematics(m, self.data)
            mujoco.mj_collision(m, self.data)
            return self._edges()
        finally:
            m.pair_margin[:] = 0.0

    def _edges(self) -> set:
        """Node pairs of the data's contacts."""
        n = self.data.ncon
        if n == 0:
            return set()
        g = self.data.contact.geom[:n]
        a, b = self._nodes[g[:, 0]], self._nodes[g[:, 1]]
        keep = (a != STATIC) & (b != STATIC) & (a != b)
        lo, hi = np.minimum(a[keep], b[keep]), np.maximum(a[keep], b[keep])
        return set(zip(lo.tolist(), hi.tolist(), strict=True))

    def _add_forces(self, f: np.ndarray, shelf: np.ndarray, steps: int) -> None:
        """Adds the last step's contact forces per node, times ``steps`` (the steps it stands
        for), to ``f`` (as `dynamics.Phi.contact_forces` counts them) and each node's whole |f|
        with the shelf to ``shelf``."""
        n = self.data.ncon
        if n == 0:
            return
        magnitude = contact_magnitudes(self.model, self.data)
        g = self.data.contact.geom[:n]
        a, b = self._nodes[g[:, 0]], self._nodes[g[:, 1]]
        nf = self.num_forces
        between = (a != STATIC) & (b != STATIC) & (a != b)
        step = np.zeros(nf)
        on_shelf = np.zeros(nf)
        for mine, other in ((a, b), (b, a)):
            counted = between & (mine >= 0)
            step += np.bincount(mine[counted], magnitude[counted], minlength=nf)
            counted = (other == STATIC) & (mine > ARM_NODE)
            on_shelf += np.bincount(mine[counted], magnitude[counted], minlength=nf)
        shelf += steps * on_shelf
        f += steps * (step + np.maximum(0.0, on_shelf - self._shelf_allowance))

    # -- the jam measure

    def _jam_approach(self, v: np.ndarray, jam: np.ndarray, steps: int) -> None:
        """Adds the commanded approach (``v``: the generalized velocity, the arm's alone
        nonzero) into the boxes blocked at the last step, over ``steps`` steps (m), to
        ``jam``."""
        m, d = self.model, self.data
        pushes = approaching(m, d, self._nodes, v)
        if not pushes or pushes_free(m, d, self._nodes, pushes):
            return  # no blocked box the jam could read: it adds only positive approach speeds
        speeds = approach_speeds(jam_contacts(m, d, self._nodes),
                                 commanded_point_velocity(m, d, v))
        for box, speed in speeds.items():
            jam[box] += max(speed, 0.0) * m.opt.timestep * steps

    # -- one world kept through a path (the judge in phi's rollouts)

    def keep_world(self, x: np.ndarray) -> np.ndarray:
        """Settles x's boxes under the still arm for ``settle_time`` in one MuJoCo world (the
        solver's warm start kept; with ``mujoco_sleep`` the boxes that come to rest sleep) and
        keeps that world as the start of every `kept_knots` run; returns the settled state
        (NaN where the settle failed)."""
        self._load(x, robot_positions(x[:ARM_DIM]), np.zeros(len(self._arm_v)))
        self._warnings = self._reset_warnings()
        knots = int(np.ceil(self.spec.config.settle_time / self.spec.knot_time - 1e-9))
        hold = np.asarray(x[:ARM_DIM], dtype=float)
        for _ in range(knots):
            self._kept_knot(hold, hold, None, False)
        self.kept = copy.copy(self.data)
        self._kept_at = (hold, None)
        x_settled = self.kept_state.copy()
        if self._kept_failed():
            x_settled[:] = np.nan
        return x_settled

    def kept_knots(self, knots: np.ndarray, trace: bool = False):
        """Steps the kept world (`keep_world`) through the knots (k, 8) from the first, which
        sets the arm, without resetting the world between knots; yields after each later knot
        (jam per kept box over the knot (m, `phi.jam`), the interaction edges seen (empty
        without ``trace``)), with ``kept_state`` then the state. A failed step (MuJoCo's
        bad-acceleration warning, a non-finite or diverged box) yields NaN jams and ends."""
        d = self.data
        mujoco.mj_copyData(d, self.model, self.kept)
        self._warnings = self._reset_warnings()
        d.qpos[self._arm_q] = robot_positions(knots[0])
        d.qvel[self._arm_v] = 0.0
        self._kept_at = (np.asarray(knots[0], dtype=float), None)
        edges = self._near_edges() if trace else set()
        for a, b in zip(knots[:-1], knots[1:], strict=True):
            jam = np.zeros(self.layout.num_boxes)
            edges |= self._kept_knot(a, b, jam, trace)
            self._kept_at = (np.asarray(b, dtype=float), None)
            if self._kept_failed():
                self.failures += 1
                yield jam * np.nan, edges
                return
            yield jam, edges
            edges = set()

    @property
    def kept_state(self) -> np.ndarray:
        """The kept world's state at the last knot `kept_knots` reached (`_read`, built when
        first asked for after that knot)."""
        u, x = self._kept_at
        if x is None:
            x = self._read(u)
            self._kept_at = (u, x)
        return x

    def _kept_sound(self) -> bool:
        """Whether `kept_state` is finite (no box `_read` marks diverged), proved from the raw
        data where every box number is well inside ``divergence_limit`` (a world-frame spin
        component is at most sqrt(3) times the largest body-frame one), else read."""
        d, limit = self.data, self.spec.config.divergence_limit
        q, v = d.qpos[self._box_qs].reshape(-1, 7), d.qvel[self._box_vs]
        if (np.abs(q).max(initial=0.0) <= limit and np.abs(v).max(initial=0.0) * SQRT3 <= limit
                and np.all(np.isfinite(self._kept_at[0]))
                and np.all(np.einsum("ij,ij->i", q[:, 3:], q[:, 3:]) > 0.0)):
            return True  # (NaN fails every comparison above)
        return bool(np.all(np.isfinite(self.kept_state)))

    def _kept_knot(self, a: np.ndarray, b: np.ndarray, jam: np.ndarray | None,
                   trace: bool) -> set:
        """One knot interval of the kept world, the arm on the straight joint-space line from
        knot a to knot b (8,) as `_step` moves it; the jam added to ``jam``; the edges seen
        (with ``trace``)."""
        q_end = robot_positions(b)
        edges = self._runs(robot_positions(a), q_end, trace, jam)
        self.data.qpos[self._arm_q] = q_end  # where the next knot starts it (`_near_edges` too)
        if trace:
            edges |= self._near_edges()
        return edges

    def _runs(self, q_start: np.ndarray, q_end: np.ndarray, trace: bool,
              jam: np.ndarray | None, forces: tuple | None = None) -> set:
        """Steps one knot interval from the data as it is, in runs of ``mujoco_sample_steps``
        steps, the arm's joints set on their line from ``q_start`` to ``q_end`` with its
        velocity before each run; after each, the run's contact edges (with ``trace``,
        returned), forces (``forces``: the (f, shelf) sums `_add_forces` adds to) and jam (added
        to ``jam``) are read and the box speeds capped."""
        m, d, n = self.model, self.data, self.substeps
        v_arm = (q_end - q_start) / self.spec.knot_time
        v = np.zeros(m.nv)  # the commanded generalized velocity the jam reads
        v[self._arm_v] = v_arm
        moving = bool(np.any(v_arm))
        chunk = self.spec.config.mujoco_sample_steps
        edges = set()
        for k in range(0, n, chunk):
            steps = min(chunk, n - k)
            d.qpos[self._arm_qs] = q_start + (q_end - q_start) * (k / n)
            d.qvel[self._arm_vs] = v_arm
            mujoco.mj_step(m, d, steps)
            if trace:
                edges |= self._edges()
            if forces is not None:
                self._add_forces(*forces, steps)
            if jam is not None and moving:
                self._jam_approach(v, jam, steps)
            self._cap_speeds()
        return edges

    def _cap_speeds(self) -> None:
        """`dynamics.cap_box_speeds` on the data, writing only the boxes it slows (a write to
        a sleeping box would wake it; a sleeping box is never capped)."""
        d = self.data
        config = self.spec.config
        if np.abs(d.qvel[self._box_vs]).max(initial=0.0) * SQRT3 <= min(config.max_box_speed,
                                                                        config.max_box_spin):
            return  # no box near either cap (|v| <= sqrt(3) max |v_i|): nothing to slow
        capped = cap_box_speeds(d.qvel, self._cap_index, config)
        if capped is d.qvel:
            return
        rows = np.any(capped[self._cap_index] != d.qvel[self._cap_index], axis=1)
        d.qvel[self._cap_index[rows]] = capped[self._cap_index[rows]]

    def _reset_warnings(self) -> int:
        """How often MuJoCo has warned of a bad position, speed or acceleration in the data
        (each time it reset the data)."""
        return sum(int(self.data.warning[w].number) for w in _RESETS)

    def _kept_failed(self) -> bool:
        """Whether the kept world failed since it was loaded: a MuJoCo warning after which it
        reset the data (`_RESETS`), or a `kept_state` that `_read` marks diverged
        (`_kept_sound`)."""
        return self._reset_warnings() > self._warnings or not self._kept_sound()
