"""Time per evaluation in Bullet at 1, 10 and 25 boxes (paper Sec. VI-B: ~1 s each).

    python benchmarks/bench_evaluation.py [--scenes 3] [--repeats 2]

For each clutter level, the first ``--scenes`` generated bookshelf scenes (seeds 0, 1, ...) whose
straight reach has an IK solution get a baseline-shaped plan: 30 knots x 0.2 s (BaselineConfig),
the tool frame on a straight line from 3 cm behind the board's front edge to the target's centre
at 0.6 x its height, the gripper horizontal and open (Drake IK at every knot, linear in joint
space between). Such straight reaches run into the clutter, so the outcomes are mixed; a
kinematic failure ends its replay early, which the "sim s" column shows.

Printed per level: wall and CPU seconds per evaluation (mean, max), simulated seconds, and the
reference measured in the same run: bare pybullet stepping of the same world for the same number
of steps with the arm parked and no monitoring (``ratio`` = evaluation / bare stepping).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from pydrake.math import RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve

from drake_clutter.common.config import BaselineConfig, EvaluationConfig
from drake_clutter.evaluation.judge import evaluate
from drake_clutter.scene.generators import generate_scene
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import Trajectory, trajectory_coordinates
from drake_clutter.worlds import bullet_world as bw
from drake_clutter.worlds.drake_world import build_planning_world

LEVELS = (1, 10, 25)
SEEDS = (-0.7, 0.9, -1.5, -2.1, 2.3, -1.2, -2.0)  # rad, an elbow-out arm posture to start IK


def straight_reach(scene: Scene, baseline: BaselineConfig) -> Trajectory | None:
    """The baseline-shaped plan described in the module docstring, or None without IK."""
    world = build_planning_world(scene)
    plant = world.plant
    context = plant.GetMyMutableContextFromRoot(world.diagram.CreateDefaultContext())
    q_all = plant.GetPositions(context)
    robot = world.robot_position_indices()
    others = np.setdiff1d(np.arange(len(q_all)), robot)
    target = scene.target_box
    z = scene.shelf.top_height + 0.6 * target.size[2]
    start = np.array([scene.shelf.front_x + 0.03, target.pose[1], z])
    goal = np.array([target.pose[0], target.pose[1], z])
    rows, q_prev = [], np.r_[SEEDS, 0.045, 0.045]
    for s in np.linspace(0.0, 1.0, baseline.num_knots):
        p = start + s * (goal - start)
        ik = InverseKinematics(plant, context, with_joint_limits=True)
        q = ik.q()
        ik.AddPositionConstraint(world.tool_frame, [0, 0, 0], plant.world_frame(), p - 1e-4,
                                 p + 1e-4)
        ik.AddOrientationConstraint(plant.world_frame(), RotationMatrix(), world.tool_frame,
                                    RotationMatrix(), 1e-3)
        prog = ik.get_mutable_prog()
        prog.AddBoundingBoxConstraint(q_all[others], q_all[others], q[others])
        prog.AddBoundingBoxConstraint([0.045, 0.045], [0.045, 0.045], q[robot[7:]])
        prog.AddQuadraticErrorCost(np.eye(7), q_prev[:7], q[robot[:7]])
        guess = q_all.copy()
        guess[robot] = q_prev
        prog.SetInitialGuess(q, guess)
        result = Solve(prog)
        if not result.is_success():
            return None
        q_prev = result.GetSolution(q)[robot]
        rows.append(q_prev)
    times = np.arange(baseline.num_knots) * baseline.knot_time
    return Trajectory(times, trajectory_coordinates(np.array(rows)))


def bare_stepping(scene: Scene, steps: int, config: EvaluationConfig) -> float:
    """Wall seconds of ``steps`` pybullet steps of the scene's world, arm parked, no checks."""
    with bw.build_bullet_world(scene, config) as world:
        q = bw.motor_positions(world, np.r_[-1.9, 0.2, 0.0, -1.9, 0.0, -0.6, 0.0, 0.045, 0.045])
        bw.reset_robot(world, q)
        bw.command_velocities(world, np.zeros(len(q)), bw.motor_forces(config))
        started = time.perf_counter()
        for _ in range(steps):
            bw.pb.stepSimulation(physicsClientId=world.client)
        return time.perf_counter() - started


def bench_level(n: int, scenes: int, repeats: int, config: EvaluationConfig) -> None:
    rows, seed = [], 0
    while len(rows) < scenes and seed < 50:
        scene = generate_scene("bookshelf", n, seed)
        seed += 1
        plan = straight_reach(scene, BaselineConfig())
        if plan is None:
            continue
        walls, cpus = [], []
        for _ in range(repeats):
            wall, cpu = time.perf_counter(), time.process_time()
            outcome = evaluate(scene, plan, config)
            walls.append(time.perf_counter() - wall)
            cpus.append(time.process_time() - cpu)
        steps = round(outcome.simulated_time / config.sim_dt)
        bare = bare_stepping(scene, steps, config)
        rows.append((scene.name, outcome.kind, outcome.simulated_time, min(walls), min(cpus), bare))
        print(f"  {scene.name:22s} {outcome.kind:18s} sim {outcome.simulated_time:5.2f} s  "
              f"eval {min(walls):.3f} s wall {min(cpus):.3f} s cpu  bare stepping {bare:.3f} s  "
              f"ratio {min(walls) / bare:.2f}", flush=True)
    walls = np.array([r[3] for r in rows])
    cpus = np.array([r[4] for r in rows])
    ratio = walls.sum() / sum(r[5] for r in rows)
    print(f"{n:2d} boxes: {walls.mean():.3f} s per evaluation (max {walls.max():.3f}), cpu "
          f"{cpus.mean():.3f} s, {np.mean([r[2] for r in rows]):.2f} s simulated; "
          f"eval / bare stepping = {ratio:.2f}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=3, help="scenes per clutter level")
    parser.add_argument("--repeats", type=int, default=2, help="timed runs per scene (min kept)")
    args = parser.parse_args()
    config = EvaluationConfig()
    print(f"sim_dt {config.sim_dt:.5f} s, {config.solver_iterations} solver iterations, checks "
          f"every {config.monitor_interval} steps; target: <= 1 s per evaluation at 25 boxes")
    for n in LEVELS:
        bench_level(n, args.scenes, args.repeats, config)


if __name__ == "__main__":
    main()
