"""phi of Sec. V: the smooth-contact dynamics x_{t+1} = phi(x_t, u_t) over the Drake SAP world.

The arm is kinematic (Sec. I, V: "we do not consider dynamics of the arm"); the boxes move by
rigid-body dynamics with contact. One call of phi advances one knot interval (``knot_time``,
0.2 s by default) in ``DynamicsConfig.substeps`` SAP steps.

State x, tangent dx and control u are `state`'s (the arm's configuration, then 13 numbers per
kept box; u the arm's configuration at the interval's end).

One step: the arm starts at x_arm with the constant velocity (u - x_arm) / knot_time and its
stiff PD servos track the straight joint-space line to u (the trajectory is linear between
knots); the boxes start at their state. After the last sub-step the arm's state is u exactly
(kinematic): d x_arm' / dx = 0 and d x_arm' / du = I. Everything phi needs is in x and u, so
phi is deterministic: the same (x, u) gives the same bits.

Contact (``DynamicsConfig.contact_model``): by default ("edges") the boxes are compliant
hydroelastic bodies with a margin (``WorldConfig.hydroelastic_margin``) against the rigid
hydroelastic arm and each other, standing on 1 mm spheres along their edges that alone meet the
shelf ("hydroelastic": the Box itself meets the shelf too); pairs within the margin enter SAP's
problem before they touch, so phi is continuous in (x, u) there; with
point contact SAP sees a pair only once it penetrates, and a perturbation that decides whether
it does at a sub-step's start changes the next velocity by a jump. Each step also yields the
contact forces between bodies (`Phi.contact_forces`, averaged over the knot): Table I's
force(q, x).

Boxes phi does not keep (see `pruning`) are welded to W where they stand: static geometry that
the arm and the kept boxes still touch. The kept set is chosen per candidate trajectory against
the current box states; a planner that moves the trajectory far re-prunes (a new `PhiSpec`).

A simulation failure (the SAP solver diverging) is not raised: `Phi.step` returns a state full
of NaN and counts it in ``Phi.failures``.
"""

from __future__ import annotations

import hashlib
import pickle
from collections import deque
from dataclasses import dataclass, fields, replace
from functools import cached_property

import numpy as np
from pydrake.math import RigidTransform

from drake_clutter.common.config import DynamicsConfig, WorldConfig, check_config
from drake_clutter.phi.jam import ACTOR, JamReader
from drake_clutter.phi.state import (
    ARM_DIM,
    BOX_DIM,
    StateLayout,
    box_state_to_pose,
    scene_box_states,
)
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import robot_positions
from drake_clutter.worlds.drake_world import (
    ROBOT_JOINTS,
    PointContactBoxes,
    World,
    build_dynamics_world,
    contact_pairs,
    set_desired_robot_state,
)

GRAVITY = 9.81  # m/s^2, Drake's default
ARM_NODE = 0  # node of the arm in interaction graphs; box i is node i + 1


# ----------------------------------------------------------------------------- spec


@dataclass(frozen=True, eq=False)
class PhiSpec:
    """Everything that defines one phi: picklable, so worker processes can build their own.

    ``dynamic_boxes`` are the kept boxes in state order; ``frozen`` maps every other scene box
    to the 7-number pose (quaternion wxyz, p_WB) where it is welded; the arm passes through
    the boxes in ``arm_passes``."""

    scene: Scene
    dynamic_boxes: tuple[str, ...]
    frozen: tuple[tuple[str, tuple[float, ...]], ...]
    knot_time: float
    config: DynamicsConfig = DynamicsConfig()
    world: WorldConfig = WorldConfig()
    variant: str = "capsules"
    arm_passes: tuple[str, ...] = ()

    @cached_property
    def key(self) -> str:
        """A digest that identifies this spec (worker processes cache their Phi by it)."""
        return hashlib.sha1(pickle.dumps(self._fields())).hexdigest()

    def _fields(self) -> tuple:
        return tuple(getattr(self, f.name) for f in fields(self))

    def __getstate__(self):
        return self._fields()

    def __setstate__(self, state):
        for f, value in zip(fields(self), state, strict=True):
            object.__setattr__(self, f.name, value)

    @property
    def layout(self) -> StateLayout:
        """The state layout of this phi."""
        return StateLayout(self.dynamic_boxes)

    @property
    def sim_time_step(self) -> float:
        """s, one SAP sub-step."""
        return self.knot_time / self.config.substeps

    def frozen_poses(self) -> dict[str, RigidTransform]:
        """name -> X_WB of the welded boxes."""
        return {name: box_state_to_pose(np.concatenate([np.asarray(p), np.zeros(6)]))
                for name, p in self.frozen}


def make_spec(scene: Scene, dynamic_boxes, box_states: dict[str, np.ndarray] | None = None,
              knot_time: float = 0.2, config: DynamicsConfig | None = None,
              world: WorldConfig | None = None, variant: str = "capsules",
              arm_passes: tuple[str, ...] = ()) -> PhiSpec:
    """A PhiSpec keeping ``dynamic_boxes`` (in order), welding the others where ``box_states``
    (name -> 13 numbers; default: resting poses) puts them; the arm passes ``arm_passes``."""
    states = scene_box_states(scene) if box_states is None else box_states
    dynamic = tuple(dynamic_boxes)
    unknown = (set(dynamic) | set(arm_passes)) - {b.name for b in scene.boxes}
    if unknown:
        raise ValueError(f"boxes not in the scene: {', '.join(sorted(unknown))}")
    frozen = tuple((b.name, tuple(float(v) for v in states[b.name][:7]))
                   for b in scene.boxes if b.name not in dynamic)
    if knot_time <= 0:
        raise ValueError(f"knot_time must be positive, got {knot_time}")
    return PhiSpec(scene, dynamic, frozen, float(knot_time), config or DynamicsConfig(),
                   world or WorldConfig(), variant, tuple(arm_passes))




def initial_state(layout: StateLayout, q_arm, box_states: dict[str, np.ndarray]) -> np.ndarray:
    """x from the arm's configuration (TRAJECTORY_JOINTS) and name -> 13-number box states
    (every kept box must be present; others are ignored)."""
    return layout.join(np.asarray(q_arm, dtype=float),
                       np.array([box_states[n] for n in layout.box_names]).reshape(-1, BOX_DIM))


def point_contact_geometry(config: DynamicsConfig) -> PointContactBoxes | None:
    """The world's box geometry for ``config.contact_model``."""
    if config.contact_model == "hydroelastic":
        return None
    if config.contact_model == "edges":
        return PointContactBoxes(config.edge_sphere_radius, compliant_box=True,
                                 edge_spacing=config.edge_sphere_spacing,
                                 board_depth=config.edge_board_depth)
    return PointContactBoxes(config.corner_sphere_radius,
                             box_shape=config.contact_model == "point")


def reach(seeds: set, links: dict) -> set:
    """The nodes reached from ``seeds`` through ``links`` ({node: its neighbours}, symmetric),
    the seeds included: the boxes a push reaches through boxes that touch."""
    reached, queue = set(seeds), deque(seeds)
    while queue:
        for other in links.get(queue.popleft(), ()):
            if other not in reached:
                reached.add(other)
                queue.append(other)
    return reached


def cap_box_speeds(values: np.ndarray, box_v: np.ndarray, config: DynamicsConfig) -> np.ndarray:
    """A plant's discrete state [q, v] with every box's angular and translational speed scaled
    down to ``max_box_spin`` / ``max_box_speed`` (continuous; a no-op below them): keeps a
    violently thrown box finite (see the config's comment). ``box_v`` (n, 6) indexes each
    box's (w_WB, v_WB) in ``values``; phi applies it after every sub-step."""
    if not len(box_v):
        return values
    v = values[box_v]
    spin = np.linalg.norm(v[:, :3], axis=1)
    speed = np.linalg.norm(v[:, 3:], axis=1)
    if np.all(spin <= config.max_box_spin) and np.all(speed <= config.max_box_speed):
        return values
    values = values.copy()
    v[:, :3] *= np.minimum(1.0, config.max_box_spin / np.maximum(spin, 1e-300))[:, None]
    v[:, 3:] *= np.minimum(1.0, config.max_box_speed / np.maximum(speed, 1e-300))[:, None]
    values[box_v] = v
    return values


# ----------------------------------------------------------------------------- phi


class PhiBase:
    """What every phi engine shares (`Phi` in Drake, `mujoco_phi.MujocoPhi`): the outputs of a
    step, the settle and rollout built on it, and the failure count. An engine implements
    ``_step(x, u, trace, forces, jam)`` -> (x', edges, f) as `Phi._step` documents."""

    def __init__(self, spec: PhiSpec):
        check_config(spec.config, section="dynamics")
        self.spec = spec
        self.layout = spec.layout
        # N per node (the arm 0, then each kept box's weight)
        self.weights = np.array([0.0, *(GRAVITY * spec.scene.box(n).mass
                                        for n in self.layout.box_names)])
        self._shelf_allowance = spec.config.shelf_force_allowance * self.weights
        self.failures = 0
        self.shelf_forces = np.full(self.num_forces, np.nan)  # of the last step_forces

    @property
    def num_forces(self) -> int:
        """Length of the force vector: one entry per node (the arm, then each kept box)."""
        return 1 + self.layout.num_boxes

    def frozen_touched(self, edges) -> set[str]:
        """Names of the frozen boxes that a set of interaction edges reaches."""
        names = [name for name, _ in self.spec.frozen]
        return {names[-n - 1] for edge in edges for n in edge if n < 0}

    def _step(self, x, u, trace: bool, forces: bool,
              jam: np.ndarray | None = None) -> tuple[np.ndarray, set, np.ndarray]:
        raise NotImplementedError

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """phi(x, u): one knot interval (see the module docstring). NaN state on failure."""
        return self._step(x, u, trace=False, forces=False)[0]

    def step_traced(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, set]:
        """phi(x, u) and the interaction edges seen during it: pairs (a, b), a < b, of nodes
        (ARM_NODE, box i + 1, frozen box j as -(j + 1)) that were in the engine's contact
        problem at some sub-step (touching, or within its margin) or came within
        ``interaction_margin`` at the start or the end of the knot. (A pair that comes closer
        than a perturbation's reach, ~1e-5 m, in mid-knot without touching may be missed.)"""
        return self._step(x, u, trace=True, forces=False)[:2]

    def step_full(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, set, np.ndarray]:
        """phi(x, u), its interaction edges (`step_traced`) and its contact forces
        (`Phi.contact_forces`, shape (1 + n,), N)."""
        return self._step(x, u, trace=True, forces=True)

    def step_forces(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """phi(x, u) and its contact forces (see `Phi.contact_forces`), without tracing. After
        it ``shelf_forces`` holds each node's summed |f| with the shelf over the knot, its
        sub-steps' mean (N, shape (1 + n,); NaN after a failed step or one without forces):
        the quantity Sec. III's kinematic failure reads in Bullet, a box's weight included."""
        x_next, _, f = self._step(x, u, trace=False, forces=True)
        return x_next, f

    def step_jam(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """phi(x, u) and each kept box's jam measure over the knot (`phi.jam`: the arm's
        commanded approach into it while a rigid world would not let it move, m, shape (n,);
        NaN after a failed step)."""
        jam = np.zeros(self.layout.num_boxes)
        x_next = self._step(x, u, trace=False, forces=False, jam=jam)[0]
        return x_next, jam if np.all(np.isfinite(x_next)) else jam * np.nan

    def step_traced_jam(self, x: np.ndarray, u: np.ndarray
                        ) -> tuple[np.ndarray, set, np.ndarray]:
        """`step_traced` and `step_jam` of one step: phi(x, u), its interaction edges and each
        kept box's jam measure over the knot (m, shape (n,); NaN after a failed step)."""
        jam = np.zeros(self.layout.num_boxes)
        x_next, edges, _ = self._step(x, u, trace=True, forces=False, jam=jam)
        return x_next, edges, jam if np.all(np.isfinite(x_next)) else jam * np.nan

    def settle(self, x: np.ndarray, seconds: float | None = None) -> np.ndarray:
        """x after the boxes rest ``seconds`` (default ``settle_time``) under the still arm:
        a start state whose boxes are at rest in phi (resting poses from a scene are not
        exactly phi's equilibrium)."""
        seconds = self.spec.config.settle_time if seconds is None else seconds
        hold = np.asarray(x[:ARM_DIM], dtype=float)
        for _ in range(int(np.ceil(seconds / self.spec.knot_time - 1e-9))):
            x = self.step(x, hold)
        return x

    def rollout(self, x0: np.ndarray, us: np.ndarray) -> np.ndarray:
        """States x_0..x_T (shape (T+1, nx)) of applying controls ``us`` (T, 8) from x0."""
        us = np.atleast_2d(np.asarray(us, dtype=float))
        xs = np.empty((len(us) + 1, self.layout.nx))
        xs[0] = x0
        for t, u in enumerate(us):
            xs[t + 1] = self.step(xs[t], u)
        return xs


class Phi(PhiBase):
    """One phi world in Drake (plant + context built once) that steps knots and traces
    interactions."""

    def __init__(self, spec: PhiSpec):
        super().__init__(spec)
        world_config = replace(spec.world, time_step=spec.sim_time_step)
        self.world: World = build_dynamics_world(
            spec.scene, spec.variant, world_config, frozen_boxes=spec.frozen_poses(),
            point_contact=point_contact_geometry(spec.config), arm_passes=spec.arm_passes)
        self.plant = self.world.plant
        self.root = self.world.diagram.CreateDefaultContext()
        self.context = self.plant.GetMyMutableContextFromRoot(self.root)
        self.plant.get_actuation_input_port().FixValue(
            self.context, np.zeros(self.plant.num_actuated_dofs()))
        self._q_default = self.plant.GetPositions(self.context).copy()
        self._robot_q = self.world.robot_position_indices()
        self._robot_v = np.array([self.plant.GetJointByName(n, self.world.robot).velocity_start()
                                  for n in ROBOT_JOINTS])
        self._box_q, self._box_v = self._box_indices()
        self._nq = self.plant.num_positions()  # v starts here in the discrete state
        self._geometry_nodes = self._map_geometry_to_nodes()
        self._contact_port = self.plant.get_contact_results_output_port()
        self._jam_reader = None  # built on the first `step_jam`

    # -- layout in the plant

    def _box_indices(self) -> tuple[np.ndarray, np.ndarray]:
        q_idx, v_idx = [], []
        for name in self.layout.box_names:
            body = self.world.box_body(name)
            q_idx.append(np.arange(body.floating_positions_start(),
                                   body.floating_positions_start() + 7))
            v_idx.append(np.arange(body.floating_velocities_start_in_v(),
                                   body.floating_velocities_start_in_v() + 6))
        shape_q, shape_v = (0, 7), (0, 6)
        return (np.array(q_idx, dtype=int).reshape(shape_q if not q_idx else (-1, 7)),
                np.array(v_idx, dtype=int).reshape(shape_v if not v_idx else (-1, 6)))

    def _map_geometry_to_nodes(self) -> dict:
        """geometry id -> interaction node: ARM_NODE, box i + 1, frozen box j -(j + 1); the
        shelf and the robot's welded base are absent."""
        plant = self.plant
        nodes = {}
        for index in plant.GetBodyIndices(self.world.robot):
            body = plant.get_body(index)
            if plant.IsAnchored(body):
                continue
            for g in plant.GetCollisionGeometriesForBody(body):
                nodes[g] = ARM_NODE
        for i, name in enumerate(self.layout.box_names):
            for g in plant.GetCollisionGeometriesForBody(self.world.box_body(name)):
                nodes[g] = i + 1
        for j, (name, _) in enumerate(self.spec.frozen):
            for g in plant.GetCollisionGeometriesForBody(self.world.box_body(name)):
                nodes[g] = -(j + 1)
        return nodes

    # -- state in and out

    def set_state(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Loads x into the plant context with the arm moving towards u; returns the arm's
        robot positions at both ends (ROBOT_JOINTS order)."""
        x, u = np.asarray(x, dtype=float), np.asarray(u, dtype=float)
        plant, ctx = self.plant, self.context
        q, v = self._q_default.copy(), np.zeros(plant.num_velocities())  # not the context's:
        # a diverged step leaves NaN there
        q_start, q_end = robot_positions(x[:ARM_DIM]), robot_positions(u)
        q[self._robot_q] = q_start
        v[self._robot_v] = (q_end - q_start) / self.spec.knot_time
        boxes = self.layout.boxes(x)
        if len(boxes):
            quats = boxes[:, :4] / np.linalg.norm(boxes[:, :4], axis=1, keepdims=True)
            q[self._box_q] = np.concatenate([quats, boxes[:, 4:7]], axis=1)
            v[self._box_v] = boxes[:, 7:]
        plant.SetPositions(ctx, q)
        plant.SetVelocities(ctx, v)
        return q_start, q_end

    def read_state(self, u: np.ndarray) -> np.ndarray:
        """x after a step: the arm at u (kinematic), the kept boxes from the plant."""
        q, v = self.plant.GetPositions(self.context), self.plant.GetVelocities(self.context)
        boxes = np.concatenate([q[self._box_q], v[self._box_v]], axis=1)
        if len(boxes):
            diverged = np.any(np.abs(boxes) > self.spec.config.divergence_limit, axis=1)
            boxes[diverged] = np.nan  # the caller counts a failure
            boxes[:, :4] /= np.linalg.norm(boxes[:, :4], axis=1, keepdims=True)
            boxes[:, :4] *= np.where(boxes[:, :1] < 0, -1.0, 1.0)
        return self.layout.join(np.asarray(u, dtype=float), boxes)

    # -- stepping

    def _jam_approach(self, v_arm: np.ndarray, jam: np.ndarray) -> None:
        """Adds one sub-step's commanded approach into blocked boxes (m) to ``jam``."""
        if self._jam_reader is None:
            nodes = {g: ACTOR if n == ARM_NODE else n - 1
                     for g, n in self._geometry_nodes.items() if n >= 0}
            self._jam_reader = JamReader(self.world, nodes)
        v = np.zeros(self.plant.num_velocities())
        v[self._robot_v] = v_arm
        for box, speed in self._jam_reader.approach(self.context, v).items():
            jam[box] += max(speed, 0.0) * self.spec.sim_time_step

    def _step(self, x, u, trace: bool, forces: bool,
              jam: np.ndarray | None = None) -> tuple[np.ndarray, set, np.ndarray]:
        f = np.zeros(self.num_forces)
        shelf = np.zeros(self.num_forces)
        self.shelf_forces = shelf * np.nan
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(u))):
            self.failures += 1  # Drake aborts on non-finite positions: never hand them over
            return np.full(self.layout.nx, np.nan), set(), f * np.nan
        q_start, q_end = self.set_state(x, u)
        n = self.spec.config.substeps
        v_arm = (q_end - q_start) / self.spec.knot_time
        edges: set = set()
        try:
            for k in range(n):
                set_desired_robot_state(self.world, self.context,
                                        q_start + (q_end - q_start) * (k + 1) / n, v_arm)
                if trace:
                    edges |= self.interactions() if k == 0 else self.contacts()
                state = self.plant.EvalUniquePeriodicDiscreteUpdate(self.context)
                if forces:  # the same cached SAP solve as the update
                    f += self.contact_forces(shelf_sum=shelf)
                if jam is not None:
                    self._jam_approach(v_arm, jam)
                self.context.SetDiscreteState(self._speed_capped(state.value()))
            if trace:
                edges |= self.interactions()
        except RuntimeError:
            self.failures += 1
            return np.full(self.layout.nx, np.nan), edges, f * np.nan
        x_next = self.read_state(u)
        if not np.all(np.isfinite(x_next)):
            self.failures += 1
            return np.full(self.layout.nx, np.nan), edges, f * np.nan
        if forces:
            self.shelf_forces = shelf / n
        return x_next, edges, f / n

    def _speed_capped(self, values: np.ndarray) -> np.ndarray:
        return cap_box_speeds(values, self._nq + self._box_v, self.spec.config)

    def contact_forces(self, shelf_sum: np.ndarray | None = None) -> np.ndarray:
        """Contact forces of the SAP step from the current plant state, per node (N, shape
        (1 + n,)): entry 0 the arm, entry i + 1 kept box i; each sums the magnitudes |f| of the
        contact forces (normal and friction together) between that node and every other object
        (arm, kept or frozen box) - Table I's forces between pairs of objects. A box's contacts
        with the shelf count only beyond ``shelf_force_allowance`` x its weight (they carry
        the weight at every knot; beyond it the box is pressed into the shelf, Sec. III's
        kinematic failure); a body's internal contacts are left out. A pair appears in both
        its nodes' entries. `step_full` averages this over a knot's sub-steps. ``shelf_sum``,
        if given, has each node's whole |f| with the shelf (its weight included) added."""
        pairs = contact_pairs(self._contact_port.Eval(self.context))
        f, shelf = self.sum_by_node(((a, b, [np.linalg.norm(force)]) for a, b, force in pairs), 1)
        if shelf_sum is not None:
            shelf_sum += shelf[:, 0]
        return f[:, 0] + np.maximum(0.0, shelf[:, 0] - self._shelf_allowance)

    def sum_by_node(self, rows, width: int) -> tuple[np.ndarray, np.ndarray]:
        """Sums per node (1 + n, width) of (geometry id A, geometry id B, row) contacts, as
        `contact_forces` counts them: (between objects, a kept box's with the shelf)."""
        f, shelf = np.zeros((self.num_forces, width)), np.zeros((self.num_forces, width))
        for id_a, id_b, row in rows:
            a, b = self._geometry_nodes.get(id_a), self._geometry_nodes.get(id_b)
            if a == b:
                continue
            if a is None or b is None:  # the shelf (or the robot's welded base)
                box = b if a is None else a
                if box is not None and box > ARM_NODE:
                    shelf[box] += row
                continue
            for node in (a, b):
                if node >= 0:
                    f[node] += row
        return f, shelf

    @property
    def contact_margin(self) -> float:
        """m: pairs this far apart are already in SAP's contact problem (the hydroelastic
        boxes' margin; 0 for point contact, where only touching pairs are)."""
        if self.spec.config.contact_model in ("hydroelastic", "edges"):
            return self.spec.world.hydroelastic_margin
        return 0.0

    def interactions(self) -> set:
        """Node pairs within ``interaction_margin`` (beyond `contact_margin`) in the current
        plant state."""
        query = self.plant.get_geometry_query_input_port().Eval(self.context)
        return self._edges(query.ComputeSignedDistancePairwiseClosestPoints(
            self.spec.config.interaction_margin + self.contact_margin))

    def contacts(self) -> set:
        """Node pairs in SAP's contact problem for a step from the current plant state:
        penetrating pairs (3x cheaper than `interactions`), or pairs within `contact_margin`."""
        query = self.plant.get_geometry_query_input_port().Eval(self.context)
        if self.contact_margin > 0:
            return self._edges(query.ComputeSignedDistancePairwiseClosestPoints(
                self.contact_margin))
        return self._edges(query.ComputePointPairPenetration())

    def _edges(self, pairs) -> set:
        edges, nodes = set(), self._geometry_nodes
        for pair in pairs:
            a, b = nodes.get(pair.id_A), nodes.get(pair.id_B)
            if a is not None and b is not None and a != b:
                edges.add((min(a, b), max(a, b)))
        return edges
