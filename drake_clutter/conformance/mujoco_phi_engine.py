"""A scenario in the MuJoCo phi's own model (``dynamics.engine: mujoco``): the model
`phi.mujoco_model.model_xml` builds (its settings, pairs with the scenario's coefficients, the
suite's capsule as the kinematic actor on slide joints), stepped as `phi.mujoco_phi.MujocoPhi`
steps a knot: runs of ``mujoco_sample_steps`` steps, the actor set on its path with its
velocity before every run, phi's box speed cap and the jam measure's reading after each.

Frames and units: W, metres, seconds, newtons.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.conformance.outcomes import Trace, knot_jam, phi_trace
from drake_clutter.conformance.scenarios import Scenario
from drake_clutter.phi.dynamics import ARM_NODE, cap_box_speeds
from drake_clutter.phi.jam import approach_speeds
from drake_clutter.phi.mujoco_model import (
    ACTOR,
    BOARD,
    ModelBox,
    box_geom,
    capsule_actor,
    model_xml,
    substeps,
)
from drake_clutter.phi.mujoco_phi import (
    STATIC,
    commanded_point_velocity,
    contact_magnitudes,
    jam_contacts,
)

PARKED = (0.0, 0.0, -5.0)  # m: a drag's unused pusher, out of reach
_NAMES = {BOARD: "board", ACTOR: "pusher"}  # the model's pair names -> the scenario's


class _Run:
    """One MuJoCo model and data, stepped through a scenario."""

    def __init__(self, scenario: Scenario, config: Config):
        self.scenario, self.config = scenario, config
        pusher = scenario.pusher
        boxes = [ModelBox(b.name, b.size, b.mass, (1.0, 0.0, 0.0, 0.0, *b.xy, scenario.box_z(b)),
                          True) for b in scenario.boxes]
        actor = capsule_actor(pusher.radius if pusher else 0.01,
                              pusher.length if pusher else 0.01,
                              pusher.start if pusher else PARKED,
                              config.dynamics.mujoco_arm_armature)

        def pair_mu(a: str, b: str) -> float | None:
            try:
                return scenario.pair(_NAMES.get(a, a), _NAMES.get(b, b))
            except KeyError:
                return None

        self.knot_steps = substeps(config.baseline.knot_time, config.dynamics)
        self.model = mujoco.MjModel.from_xml_string(model_xml(
            scenario.shelf, boxes, actor, pair_mu, config.dynamics, config.baseline.knot_time))
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.dt = m.opt.timestep
        self.actor_q = np.array([m.joint(j).qposadr[0] for j in actor.joints])
        self.actor_v = np.array([m.joint(j).dofadr[0] for j in actor.joints])
        joints = [m.body(box_geom(b.name)).jntadr[0] for b in scenario.boxes]
        self.box_v = np.array([m.jnt_dofadr[j] + np.arange(6) for j in joints])
        self.bodies = [m.body(box_geom(b.name)).id for b in scenario.boxes]
        self.nodes = np.full(m.ngeom, STATIC, dtype=np.int64)
        self.nodes[[m.geom(g).id for g in actor.geoms]] = ARM_NODE
        for i, b in enumerate(scenario.boxes):
            self.nodes[m.geom_bodyid == m.body(box_geom(b.name)).id] = i + 1
            self.data.qvel[self.box_v[i, :3]] = b.velocity
        self.approach: list[np.ndarray] = []  # per step, per box: m into blocked boxes
        mujoco.mj_forward(m, self.data)

    def _actor_at(self, t: float) -> np.ndarray:
        """The actor's slide positions (its centre in W, relative to its start) at time t."""
        pusher = self.scenario.pusher
        if pusher is None:
            return np.zeros(3)
        return np.array([pusher.x_at(t) - pusher.start[0], 0.0, 0.0])

    def step(self, t: float, steps: int) -> np.ndarray:
        """One run of ``steps`` steps from time t (the actor set on its path, moving to
        where it is at the run's end); returns each box's summed |f| with the shelf at the
        run's last step (N)."""
        m, d = self.model, self.data
        q, q_next = self._actor_at(t), self._actor_at(t + steps * self.dt)
        v = (q_next - q) / (steps * self.dt)
        d.qpos[self.actor_q] = q
        d.qvel[self.actor_v] = v
        mujoco.mj_step(m, d, steps)
        v_commanded = np.zeros(m.nv)
        v_commanded[self.actor_v] = v
        approach = np.zeros(len(self.bodies))
        speeds = approach_speeds(jam_contacts(m, d, self.nodes),
                                 commanded_point_velocity(m, d, v_commanded))
        for box, speed in speeds.items():
            approach[box] = max(speed, 0.0) * self.dt * steps
        self.approach.append(approach)
        d.qvel[:] = cap_box_speeds(d.qvel, self.box_v[:, [3, 4, 5, 0, 1, 2]],
                                   self.config.dynamics)
        return self.static_forces()

    def static_forces(self) -> np.ndarray:
        """Each box's summed |f| with the shelf in the last step (N)."""
        n = self.data.ncon
        f = np.zeros(len(self.bodies))
        if n == 0:
            return f
        magnitude = contact_magnitudes(self.model, self.data)
        g = self.data.contact.geom[:n]
        a, b = self.nodes[g[:, 0]], self.nodes[g[:, 1]]
        for mine, other in ((a, b), (b, a)):
            counted = (other == STATIC) & (mine > ARM_NODE)
            np.add.at(f, mine[counted] - 1, magnitude[counted])
        return f

    def jam(self) -> np.ndarray:
        """The jam measure per box (m) over one knot's runs in a row (`knot_jam`)."""
        runs = max(1, self.knot_steps // self.config.dynamics.mujoco_sample_steps)
        return knot_jam(self.approach, runs, len(self.bodies))

    def sample(self) -> tuple[np.ndarray, np.ndarray]:
        """Box centres (n, 3) and rotations (n, 3, 3) in W now."""
        mujoco.mj_kinematics(self.model, self.data)
        return (self.data.xpos[self.bodies].copy(),
                self.data.xmat[self.bodies].reshape(-1, 3, 3).copy())

    def failed(self) -> bool:
        """MuJoCo reset the data after a bad acceleration."""
        return self.data.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)].number > 0


def simulate(scenario: Scenario, config: Config) -> Trace:
    """Runs ``scenario`` in the MuJoCo phi's model (``config.dynamics``, its step from
    ``config.baseline.knot_time``); samples after every run of ``mujoco_sample_steps``
    steps. A failed step ends the trace with its failure named."""
    started = time.perf_counter()
    run = _Run(scenario, config)
    chunk = config.dynamics.mujoco_sample_steps
    steps = int(np.ceil(scenario.duration / run.dt - 1e-9))
    p0, R0 = run.sample()
    times, positions, rotations, forces = [0.0], [p0], [R0], []
    failure = ""
    for k in range(0, steps, chunk):
        forces.append(run.step(k * run.dt, min(chunk, steps - k)))
        p, R = run.sample()
        if run.failed() or not np.all(np.isfinite(p)):
            failure = f"MuJoCo step {k}: bad acceleration or non-finite box state"
            break
        times.append(min(k + chunk, steps) * run.dt)
        positions.append(p)
        rotations.append(R)
    return phi_trace((times, positions, rotations), forces, len(scenario.boxes),
                     time.perf_counter() - started, failure, run.jam())
