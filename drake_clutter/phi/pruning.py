"""Which boxes phi keeps dynamic for a candidate trajectory (the paper's Sec. I remark: "the
optimization only needs to consider obstacles in the environment that would be impacted").

A box is kept when it comes within ``DynamicsConfig.prune_margin`` of the arm anywhere along
the trajectory's swept volume (the arm sampled ``prune_samples_per_knot`` times per knot
interval, linear in joint space as the trajectory is), or, transitively, when it stands within
``prune_contact_range`` of a kept box. All others are welded where they stand in phi (they stay
in the evaluation). A pushed box can travel farther than any fixed range, so
`make_pruned_spec` then rolls the trajectory out in the pruned phi and makes every frozen box
that the arm or a kept box reached dynamic too (``prune_rounds`` times at most).

Pruning looks at the CURRENT box states and one trajectory: a planner whose iterations move the
trajectory or the boxes far re-prunes and builds a new phi (`make_pruned_spec` again);
`rollouts_touch_frozen` tells it when a frozen box is being reached.

Distances are Drake signed distances (m) between the arm's geometry (the chosen URDF variant)
and the boxes' Box shapes, all in W.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet, Role

from drake_clutter.common.config import DynamicsConfig, WorldConfig
from drake_clutter.phi.dynamics import PhiSpec, initial_state, make_spec, reach
from drake_clutter.phi.engines import build_phi
from drake_clutter.phi.state import box_state_to_pose, scene_box_states
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import robot_positions
from drake_clutter.worlds.drake_world import PointContactBoxes, build_dynamics_world


@dataclass(frozen=True)
class PruneReport:
    """What pruning kept: ``kept`` (scene order), of which ``near_arm`` came within the margin of
    the swept arm; ``num_boxes`` in the scene."""

    kept: tuple[str, ...]
    near_arm: tuple[str, ...]
    num_boxes: int
    added: tuple[str, ...] = ()  # frozen boxes a checking rollout reached (made dynamic)
    rounds: int = 0  # checking rollouts done

    def summary(self) -> str:
        """One line, e.g. 'kept 6 of 25 boxes (4 near the arm, 1 added by 2 rollouts)'."""
        return (f"kept {len(self.kept)} of {self.num_boxes} boxes "
                f"({len(self.near_arm)} near the arm, {len(self.added)} added by "
                f"{self.rounds} checking rollouts)")


def swept_samples(arm_path: np.ndarray, samples_per_knot: int) -> np.ndarray:
    """Arm configurations (TRAJECTORY_JOINTS rows) along a knot path, ``samples_per_knot`` per
    interval (linear in joint space), the last knot included."""
    path = np.atleast_2d(np.asarray(arm_path, dtype=float))
    if len(path) == 1:
        return path
    s = np.arange(samples_per_knot) / samples_per_knot
    rows = [(1 - si) * a + si * b for a, b in zip(path[:-1], path[1:], strict=True) for si in s]
    return np.vstack(rows + [path[-1]])


def prune(scene: Scene, arm_path: np.ndarray, box_states: dict[str, np.ndarray] | None = None,
          config: DynamicsConfig | None = None, world_config: WorldConfig | None = None,
          variant: str = "capsules", other_paths: tuple[np.ndarray, ...] = ()) -> PruneReport:
    """The boxes a trajectory (knot rows of TRAJECTORY_JOINTS) can affect, see the module doc;
    with ``other_paths`` (more such trajectories), those any of them can affect.

    ``box_states``: name -> 13-number state (default: every box resting at its scene pose).
    """
    config = config or DynamicsConfig()
    states = scene_box_states(scene) if box_states is None else box_states
    world = build_dynamics_world(scene, variant, world_config or WorldConfig(),
                                 point_contact=PointContactBoxes(config.corner_sphere_radius))
    root = world.diagram.CreateDefaultContext()
    context = world.plant.GetMyMutableContextFromRoot(root)
    for box in scene.boxes:
        world.plant.SetFreeBodyPose(context, world.box_body(box.name),
                                    box_state_to_pose(states[box.name]))
    owner = _geometry_owners(world)
    neighbours = _box_neighbours(world, context, owner, config.prune_contact_range)
    _only_arm_with_boxes(world, root, owner)
    near_arm: set[str] = set()
    samples = np.vstack([swept_samples(path, config.prune_samples_per_knot)
                         for path in (arm_path, *other_paths)])
    for q in robot_positions(samples):
        world.set_robot_positions(context, q)
        for a, b in _close_pairs(world, context, owner, config.prune_margin):
            near_arm.add(b if a == "arm" else a)
        if len(near_arm) == len(scene.boxes):
            break
    kept = reach(near_arm, neighbours)
    order = [b.name for b in scene.boxes]
    return PruneReport(tuple(n for n in order if n in kept),
                       tuple(n for n in order if n in near_arm), len(order))


def _geometry_owners(world) -> dict:
    """geometry id -> 'arm' or a box name (static geometry is absent)."""
    plant, owner = world.plant, {}
    for index in plant.GetBodyIndices(world.robot):
        body = plant.get_body(index)
        if not plant.IsAnchored(body):
            owner.update(dict.fromkeys(plant.GetCollisionGeometriesForBody(body), "arm"))
    for name in world.box_names:
        owner.update(dict.fromkeys(
            plant.GetCollisionGeometriesForBody(world.box_body(name)), name))
    return owner


def _only_arm_with_boxes(world, root, owner: dict) -> None:
    """Filters, in the root context ``root``, every geometry pair but the arm's with a box out of
    the world's distance queries (the swept arm asks only those: the shelf's pairs with the
    boxes resting on it are the most numerous otherwise)."""
    arm = GeometrySet([g for g, name in owner.items() if name == "arm"])
    inspector = world.scene_graph.model_inspector()
    others = GeometrySet([g for g in inspector.GetAllGeometryIds(Role.kProximity)
                          if owner.get(g) != "arm"])
    static = GeometrySet([g for g in inspector.GetAllGeometryIds(Role.kProximity)
                          if g not in owner])
    manager = world.scene_graph.collision_filter_manager(
        world.scene_graph.GetMyMutableContextFromRoot(root))
    manager.Apply(CollisionFilterDeclaration().ExcludeWithin(arm).ExcludeWithin(others)
                  .ExcludeBetween(arm, static))


def _close_pairs(world, context, owner: dict, distance: float) -> set[tuple[str, str]]:
    query = world.plant.get_geometry_query_input_port().Eval(context)
    pairs = set()
    for pair in query.ComputeSignedDistancePairwiseClosestPoints(distance):
        a, b = owner.get(pair.id_A), owner.get(pair.id_B)
        if a is not None and b is not None and a != b:
            pairs.add((a, b))
    return pairs


def _box_neighbours(world, context, owner, distance: float) -> dict[str, set[str]]:
    neighbours: dict[str, set[str]] = {}
    for a, b in _close_pairs(world, context, owner, distance):
        if "arm" not in (a, b):
            neighbours.setdefault(a, set()).add(b)
            neighbours.setdefault(b, set()).add(a)
    return neighbours


def make_pruned_spec(scene: Scene, arm_path: np.ndarray,
                     box_states: dict[str, np.ndarray] | None = None, knot_time: float = 0.2,
                     config: DynamicsConfig | None = None,
                     world_config: WorldConfig | None = None,
                     variant: str = "capsules", other_paths: tuple[np.ndarray, ...] = ()
                     ) -> tuple[PhiSpec, PruneReport]:
    """The phi of a candidate trajectory (knot rows of TRAJECTORY_JOINTS, the first being the
    start), pruned against the current ``box_states``, then checked by rolling the path out:
    frozen boxes that a kept box or the arm reached become dynamic, up to ``prune_rounds``
    rounds (``PruneReport.rounds``/``added`` say what happened); none when no box is frozen
    (every box kept: there is nothing for a rollout to find). ``other_paths`` (same start):
    one phi for all of them, pruned and checked against each, so they can be compared in it."""
    config = config or DynamicsConfig()
    world_config = world_config or WorldConfig()
    states = scene_box_states(scene) if box_states is None else box_states
    report = prune(scene, arm_path, states, config, world_config, variant, other_paths)
    kept, added, rounds = set(report.kept), set(), 0
    spec = make_spec(scene, _in_scene_order(scene, kept), states, knot_time, config,
                     world_config, variant)
    while rounds < config.prune_rounds and spec.frozen:
        rounds += 1
        touched = rollouts_touch_frozen(spec, (arm_path, *other_paths), states)
        if not touched:
            break
        kept |= touched
        added |= touched
        spec = make_spec(scene, _in_scene_order(scene, kept), states, knot_time, config,
                         world_config, variant)
    report = PruneReport(spec.dynamic_boxes, report.near_arm, report.num_boxes,
                         tuple(_in_scene_order(scene, added)), rounds)
    return spec, report


def _in_scene_order(scene: Scene, names) -> list[str]:
    return [b.name for b in scene.boxes if b.name in names]


def rollouts_touch_frozen(spec: PhiSpec, arm_paths: tuple[np.ndarray, ...],
                          box_states: dict[str, np.ndarray]) -> set[str]:
    """Frozen boxes that the arm or a kept box comes within ``interaction_margin`` of when
    phi plays any of ``arm_paths`` (knot rows) from the settled start: one phi for all of
    them, settled once per distinct start configuration."""
    phi = build_phi(spec)
    settled: list[tuple[np.ndarray, np.ndarray]] = []
    touched: set[str] = set()
    for path in arm_paths:
        path = np.asarray(path, dtype=float)
        x = next((x0 for q0, x0 in settled if np.array_equal(q0, path[0])), None)
        if x is None:
            x = phi.settle(initial_state(spec.layout, path[0], box_states))
            settled.append((path[0], x))
        for u in path[1:]:
            x, edges = phi.step_traced(x, u)
            touched |= phi.frozen_touched(edges)
            if not np.all(np.isfinite(x)):
                break
    return touched

