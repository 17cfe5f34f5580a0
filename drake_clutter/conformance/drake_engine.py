"""A scenario in phi's own Drake world: `worlds.drake_world.build_pusher_world` (phi's plant
settings, box geometry, shelf and collision rules, the capsule in place of the arm), stepped as
phi steps a knot: sub-steps of ``baseline.knot_time / dynamics.substeps``, the PD servos told
where the pusher is at each sub-step's end, and phi's box speed cap after each.

Frames and units: W, metres, seconds, newtons.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from pydrake.multibody.math import SpatialVelocity

from drake_clutter.common.config import Config
from drake_clutter.conformance.friction import drake_coefficients
from drake_clutter.conformance.outcomes import Trace, knot_jam, phi_trace
from drake_clutter.conformance.scenarios import Scenario, scenario_scene
from drake_clutter.phi.dynamics import cap_box_speeds, point_contact_geometry
from drake_clutter.phi.jam import ACTOR, JamReader
from drake_clutter.worlds.drake_world import (
    CapsulePusher,
    World,
    build_pusher_world,
    contact_pairs,
)


def build_world(scenario: Scenario, config: Config) -> World:
    """phi's world of the scenario at phi's sub-step (pair frictions realised exactly, so
    ``world.friction_as_bullet`` is off here)."""
    coefficients = drake_coefficients(scenario)
    world_config = replace(config.world, friction_as_bullet=False,
                           time_step=config.baseline.knot_time / config.dynamics.substeps)
    pusher = scenario.pusher
    capsule = CapsulePusher(pusher.radius if pusher else 0.01, pusher.length if pusher else 0.01,
                            coefficients.get("pusher", 1.0))
    return build_pusher_world(scenario_scene(scenario, coefficients), capsule, world_config,
                              point_contact=point_contact_geometry(config.dynamics),
                              shelf_friction=coefficients["board"])


class _Run:
    """One world and context, stepped through a scenario."""

    def __init__(self, scenario: Scenario, config: Config):
        self.scenario, self.config = scenario, config
        self.world = build_world(scenario, config)
        plant = self.world.plant
        self.root = self.world.diagram.CreateDefaultContext()
        self.context = plant.GetMyMutableContextFromRoot(self.root)
        self.dt = plant.time_step()
        self.bodies = [self.world.box_body(b.name) for b in scenario.boxes]
        self.box_v = np.array([np.arange(b.floating_velocities_start_in_v(),
                                         b.floating_velocities_start_in_v() + 6)
                               for b in self.bodies]) + plant.num_positions()
        self.shelf_geometry = {g for i in plant.GetBodyIndices(self.world.shelf)
                               for g in plant.GetCollisionGeometriesForBody(plant.get_body(i))}
        self.box_geometry = [set(plant.GetCollisionGeometriesForBody(b)) for b in self.bodies]
        self.jam_reader = JamReader(self.world, self._jam_nodes())
        self.approach: list[np.ndarray] = []  # per sub-step, per box: m into blocked boxes
        self._start()

    def _jam_nodes(self) -> dict:
        plant = self.world.plant
        nodes = {g: i for i, ids in enumerate(self.box_geometry) for g in ids}
        for index in plant.GetBodyIndices(self.world.robot):
            for g in plant.GetCollisionGeometriesForBody(plant.get_body(index)):
                nodes[g] = ACTOR
        return nodes

    def _pusher_target(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        pusher = self.scenario.pusher
        if pusher is None:  # parked far below the board, out of reach
            return np.array([0.0, 0.0, -5.0]), np.zeros(3)
        q = np.array([pusher.x_at(t), pusher.start[1], pusher.start[2]])
        return q, np.array([pusher.speed_at(t), 0.0, 0.0])

    def _start(self) -> None:
        plant, ctx = self.world.plant, self.context
        plant.get_actuation_input_port().FixValue(ctx, np.zeros(plant.num_actuated_dofs()))
        q, v = self._pusher_target(0.0)
        pusher = self.world.robot
        plant.SetPositions(ctx, pusher, q)
        plant.SetVelocities(ctx, pusher, v)
        for box, body in zip(self.scenario.boxes, self.bodies, strict=True):
            velocity = SpatialVelocity(np.zeros(3), np.asarray(box.velocity, dtype=float))
            plant.SetFreeBodySpatialVelocity(ctx, body, velocity)

    def static_forces(self) -> np.ndarray:
        """Each box's summed |f| with the shelf in the step from the current state (N)."""
        pairs = contact_pairs(self.world.plant.get_contact_results_output_port().Eval(self.context))
        f = np.zeros(len(self.bodies))
        for a, b, force in pairs:
            other = b if a in self.shelf_geometry else (a if b in self.shelf_geometry else None)
            if other is None:
                continue
            for i, ids in enumerate(self.box_geometry):
                if other in ids:
                    f[i] += np.linalg.norm(force)
        return f

    def jam(self) -> np.ndarray:
        """phi's jam measure per box (m) over one knot's sub-steps in a row (`knot_jam`)."""
        return knot_jam(self.approach, self.config.dynamics.substeps, len(self.bodies))

    def sample(self) -> tuple[np.ndarray, np.ndarray]:
        """Box centres (n, 3) and rotations (n, 3, 3) in W now."""
        poses = [self.world.plant.EvalBodyPoseInWorld(self.context, b) for b in self.bodies]
        return (np.array([X.translation() for X in poses]),
                np.array([X.rotation().matrix() for X in poses]))

    def step(self, t: float) -> np.ndarray:
        """One sub-step from time t; returns the static forces of that step."""
        plant = self.world.plant
        q, v = self._pusher_target(t + self.dt)
        plant.get_desired_state_input_port(self.world.robot).FixValue(self.context,
                                                                      np.concatenate([q, v]))
        state = plant.EvalUniquePeriodicDiscreteUpdate(self.context)
        forces = self.static_forces()
        v_commanded = np.zeros(plant.num_velocities())
        plant.SetVelocitiesInArray(self.world.robot, v, v_commanded)
        approach = np.zeros(len(self.bodies))
        for box, speed in self.jam_reader.approach(self.context, v_commanded).items():
            approach[box] = max(speed, 0.0) * self.dt
        self.approach.append(approach)
        self.context.SetDiscreteState(cap_box_speeds(state.value(), self.box_v,
                                                     self.config.dynamics))
        return forces


def simulate(scenario: Scenario, config: Config) -> Trace:
    """Runs ``scenario`` in phi's world (``config.world``, ``config.dynamics``, phi's sub-step
    from ``config.baseline.knot_time``); samples every sub-step. A diverged step ends the trace
    with its failure named."""
    started = time.perf_counter()
    run = _Run(scenario, config)
    steps = int(np.ceil(scenario.duration / run.dt - 1e-9))
    p0, R0 = run.sample()
    times, positions, rotations, forces = [0.0], [p0], [R0], []
    failure = ""
    for k in range(steps):
        try:
            forces.append(run.step(k * run.dt))
        except RuntimeError as error:
            failure = f"Drake step {k}: {str(error).splitlines()[0]}"
            break
        p, R = run.sample()
        if not np.all(np.isfinite(p)):
            failure = f"Drake step {k}: non-finite box state"
            break
        times.append((k + 1) * run.dt)
        positions.append(p)
        rotations.append(R)
    return phi_trace((times, positions, rotations), forces, len(scenario.boxes),
                     time.perf_counter() - started, failure, run.jam())
