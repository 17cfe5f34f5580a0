"""A scenario in a Bullet world with the judge's engine settings (`bullet_world.new_client`):
the shelf and boxes built as the judge builds them, the capsule on three prismatic joints driven
as the judge drives the arm (velocity motors with ``evaluation.arm_max_force``, re-aimed every
``monitor_interval`` steps at where the pusher must be by the next update).

Frames and units: W, metres, seconds, newtons.
"""

from __future__ import annotations

import time

import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.conformance.friction import bullet_coefficients
from drake_clutter.conformance.outcomes import Trace
from drake_clutter.conformance.scenarios import Pusher, Scenario, scenario_scene
from drake_clutter.worlds.bullet_world import add_boxes, add_shelf, new_client, pb

_PARKED = np.array([0.0, 0.0, -5.0])  # m: where a drag's unused pusher waits, out of reach


def _add_pusher(client: int, pusher: Pusher | None, friction: float) -> int:
    radius, length = (pusher.radius, pusher.length) if pusher else (0.01, 0.01)
    capsule = pb.createCollisionShape(
        pb.GEOM_CAPSULE, radius=radius, height=length,
        collisionFrameOrientation=pb.getQuaternionFromEuler([np.pi / 2, 0.0, 0.0]),
        physicsClientId=client)
    body = pb.createMultiBody(
        0.0, -1, -1, [0.0, 0.0, 0.0], linkMasses=[0.1, 0.1, 1.0],
        linkCollisionShapeIndices=[-1, -1, capsule], linkVisualShapeIndices=[-1, -1, -1],
        linkPositions=[[0.0, 0.0, 0.0]] * 3, linkOrientations=[[0.0, 0.0, 0.0, 1.0]] * 3,
        linkInertialFramePositions=[[0.0, 0.0, 0.0]] * 3,
        linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * 3, linkParentIndices=[0, 1, 2],
        linkJointTypes=[pb.JOINT_PRISMATIC] * 3,
        linkJointAxis=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        physicsClientId=client)
    for link in range(3):
        pb.changeDynamics(body, link, lateralFriction=friction, linearDamping=0.0,
                          angularDamping=0.0, jointDamping=0.0, physicsClientId=client)
    return body


def _pusher_target(pusher: Pusher | None, t: float) -> np.ndarray:
    if pusher is None:
        return _PARKED
    return np.array([pusher.x_at(t), pusher.start[1], pusher.start[2]])


def _static_forces(client: int, shelf: int, boxes: tuple[int, ...]) -> np.ndarray:
    index = {body: i for i, body in enumerate(boxes)}
    f = np.zeros(len(boxes))
    for point in pb.getContactPoints(bodyA=shelf, physicsClientId=client):
        i = index.get(point[2])
        if i is not None:
            f[i] += np.sqrt(point[9] ** 2 + point[10] ** 2 + point[12] ** 2)
    return f


def _sample(client: int, boxes: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    p, R = [], []
    for body in boxes:
        position, quat = pb.getBasePositionAndOrientation(body, physicsClientId=client)
        p.append(position)
        R.append(np.array(pb.getMatrixFromQuaternion(quat)).reshape(3, 3))
    return np.array(p), np.array(R)


def simulate(scenario: Scenario, config: Config) -> Trace:
    """Runs ``scenario`` in Bullet with ``config.evaluation``'s engine settings; samples every
    ``monitor_interval`` steps (the judge's control period)."""
    started = time.perf_counter()
    evaluation = config.evaluation
    coefficients = bullet_coefficients(scenario)
    client = new_client(evaluation)
    try:
        scene = scenario_scene(scenario, coefficients)
        shelf = add_shelf(client, scene, coefficients["board"])
        boxes = add_boxes(client, scene)
        pusher = _add_pusher(client, scenario.pusher, coefficients.get("pusher", 1.0))
        for link in range(3):
            pb.setCollisionFilterPair(pusher, shelf, link, -1, 0, physicsClientId=client)
        for body, box in zip(boxes, scenario.boxes, strict=True):
            pb.resetBaseVelocity(body, list(box.velocity), [0.0, 0.0, 0.0],
                                 physicsClientId=client)
        start = _pusher_target(scenario.pusher, 0.0)
        speed = scenario.pusher.speed_at(0.0) if scenario.pusher else 0.0
        for j in range(3):
            pb.resetJointState(pusher, j, float(start[j]), speed if j == 0 else 0.0,
                               physicsClientId=client)
        return _run(scenario, config, client, shelf, boxes, pusher, started)
    finally:
        pb.disconnect(client)


def _run(scenario: Scenario, config: Config, client: int, shelf: int, boxes: tuple[int, ...],
         pusher: int, started: float) -> Trace:
    evaluation = config.evaluation
    span = evaluation.monitor_interval * evaluation.sim_dt
    updates = int(np.ceil(scenario.duration / span - 1e-9))
    p0, R0 = _sample(client, boxes)
    times, positions, rotations = [0.0], [p0], [R0]
    forces = [_static_forces(client, shelf, boxes)]
    for k in range(updates):
        q = np.array([s[0] for s in pb.getJointStates(pusher, [0, 1, 2], physicsClientId=client)])
        velocity = (_pusher_target(scenario.pusher, (k + 1) * span) - q) / span
        pb.setJointMotorControlArray(pusher, [0, 1, 2], pb.VELOCITY_CONTROL,
                                     targetVelocities=list(velocity),
                                     forces=[evaluation.arm_max_force] * 3,
                                     physicsClientId=client)
        for _ in range(evaluation.monitor_interval):
            pb.stepSimulation(physicsClientId=client)
        p, R = _sample(client, boxes)
        times.append((k + 1) * span)
        positions.append(p)
        rotations.append(R)
        forces.append(_static_forces(client, shelf, boxes))
    return Trace("bullet", np.array(times), np.array(positions), np.array(rotations),
                 np.array(forces), time.perf_counter() - started)
