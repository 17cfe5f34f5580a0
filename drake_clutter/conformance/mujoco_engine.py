"""A scenario in MuJoCo, the suite's reference engine (optional: ``pip install mujoco``).

The model is written as MJCF text: the shelf's parts as static boxes, each box a free body of
the scenario's mass, the capsule on a mocap body (kinematic: it goes exactly where the script
says). Every pair that may touch is an explicit ``<pair>`` with the scenario's coefficient (all
automatic contacts are off), so no combination rule is involved. Two settings: "default"
(MuJoCo's defaults: 2 ms step, solref 0.02 1) and "stiff" (1 ms, solref 0.002 1).

Frames and units: W, metres, seconds, newtons.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np

from drake_clutter.conformance.outcomes import Trace
from drake_clutter.conformance.scenarios import Scenario
from drake_clutter.scene.shelf import shelf_boxes

SETTINGS = {"default": (0.002, "0.02 1"), "stiff": (0.001, "0.002 1")}  # time step s, solref
SAMPLE_PERIOD = 0.01  # s between samples of the trace
_PARKED = (0.0, 0.0, -5.0)  # m: a drag's unused pusher, out of reach


def _v(values) -> str:
    return " ".join(f"{float(v)!r}" for v in values)


def model_xml(scenario: Scenario, setting: str = "default") -> str:
    """The scenario's MJCF text under a setting of `SETTINGS`."""
    step, solref = SETTINGS[setting]
    shelf = scenario.shelf
    origin = np.array([*shelf.center_xy, shelf.top_height])
    parts = [f'<geom name="shelf_{name}" type="box" pos="{_v(origin + np.array(centre))}" '
             f'size="{_v(np.array(size) / 2)}" contype="0" conaffinity="0"/>'
             for name, centre, size in shelf_boxes(shelf)]
    boxes = [f'<body name="{b.name}" pos="{_v([*b.xy, scenario.box_z(b)])}"><freejoint/>'
             f'<geom name="{b.name}" type="box" size="{_v(np.array(b.size) / 2)}" '
             f'mass="{b.mass!r}" contype="0" conaffinity="0"/></body>' for b in scenario.boxes]
    pusher = scenario.pusher
    radius, half = (pusher.radius, pusher.length / 2) if pusher else (0.01, 0.005)
    start = pusher.start if pusher else _PARKED
    boxes.append(f'<body name="pusher" mocap="true" pos="{_v(start)}"><geom name="pusher" '
                 f'type="capsule" fromto="0 {-half!r} 0 0 {half!r} 0" size="{radius!r}" '
                 f'contype="0" conaffinity="0"/></body>')
    pairs = []
    for a, b, mu in scenario.friction:
        geoms_a = [f"shelf_{name}" for name, _, _ in shelf_boxes(shelf)] if a == "board" else [a]
        pairs += [f'<pair geom1="{g}" geom2="{b}" condim="3" friction="{mu!r} {mu!r} 0.005 '
                  f'0.0001 0.0001" solref="{solref}"/>' for g in geoms_a]
    return (f'<mujoco model="{scenario.name}"><option timestep="{step!r}" gravity="0 0 -9.81"/>'
            f'<worldbody>{"".join(parts)}{"".join(boxes)}</worldbody>'
            f'<contact>{"".join(pairs)}</contact></mujoco>')


def _static_forces(model, data, shelf_geoms: set[int], box_geoms: list[int]) -> np.ndarray:
    f = np.zeros(len(box_geoms))
    wrench = np.zeros(6)
    for i in range(data.ncon):
        contact = data.contact[i]
        g1, g2 = int(contact.geom1), int(contact.geom2)
        other = g2 if g1 in shelf_geoms else (g1 if g2 in shelf_geoms else None)
        if other is None or other not in box_geoms:
            continue
        mujoco.mj_contactForce(model, data, i, wrench)
        f[box_geoms.index(other)] += np.linalg.norm(wrench[:3])
    return f


def simulate(scenario: Scenario, setting: str = "default") -> Trace:
    """Runs ``scenario`` in MuJoCo under ``setting``; samples every 10 ms."""
    started = time.perf_counter()
    model = mujoco.MjModel.from_xml_string(model_xml(scenario, setting))
    data = mujoco.MjData(model)
    bodies = [model.body(b.name).id for b in scenario.boxes]
    box_geoms = [model.geom(b.name).id for b in scenario.boxes]
    shelf_geoms = {model.geom(f"shelf_{name}").id for name, _, _ in shelf_boxes(scenario.shelf)}
    for body, box in zip(bodies, scenario.boxes, strict=True):
        dof = model.jnt_dofadr[model.body_jntadr[body]]
        data.qvel[dof:dof + 3] = box.velocity
    mujoco.mj_forward(model, data)
    per_sample = max(1, round(SAMPLE_PERIOD / model.opt.timestep))
    samples = int(np.ceil(scenario.duration / (per_sample * model.opt.timestep) - 1e-9))
    times, positions, rotations = [0.0], [data.xpos[bodies].copy()], [
        data.xmat[bodies].reshape(-1, 3, 3).copy()]
    forces = [_static_forces(model, data, shelf_geoms, box_geoms)]
    for k in range(samples):
        for _ in range(per_sample):
            if scenario.pusher is not None:
                data.mocap_pos[0, 0] = scenario.pusher.x_at(data.time + model.opt.timestep)
            mujoco.mj_step(model, data)
        times.append((k + 1) * per_sample * model.opt.timestep)
        positions.append(data.xpos[bodies].copy())
        rotations.append(data.xmat[bodies].reshape(-1, 3, 3).copy())
        forces.append(_static_forces(model, data, shelf_geoms, box_geoms))
    return Trace(f"mujoco_{setting}", np.array(times), np.array(positions), np.array(rotations),
                 np.array(forces), time.perf_counter() - started)
