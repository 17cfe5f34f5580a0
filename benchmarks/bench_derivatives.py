"""Benchmark of phi and its Jacobians: pruning, colouring, workers against brute force.

For bookshelf scenes with 1, 5, 10, 15, 20, 25 boxes (seed 0: the same target at every level)
and a baseline-like straight reach (drake_clutter/testing/reach_paths.py; 30 knots, 0.2 s
apart) it prints:
kept boxes, phi's time per knot (``substeps`` SAP steps, contact forces included), phi
evaluations per finite-differenced knot against brute force's ndx + nu + 1 on the whole scene,
the knots differentiated by AutoDiffXd instead (``dynamics.derivative_method``), the whole horizon
linearised serially and with the worker pool, and the brute-force horizon on the unpruned
scene: its per-knot cost is (ndx + nu + 1) x the measured full-scene step time at that knot
(summed over the horizon), checked against one real dense Jacobian at the middle knot.
``--validate`` adds the finite-difference vs AutoDiffXd comparison on phi as configured.
``--compare FIELD=VALUE`` (repeatable) runs every level a second time with those overrides on
top of the configuration, right after the first, so old and new phi are timed in the same run;
``--no-brute-force`` leaves the brute-force columns out (they take minutes per level).
Both phi engines in one run: ``--compare dynamics.engine=mujoco`` (the rows labelled
"compare" are the MuJoCo phi's).

    python benchmarks/bench_derivatives.py [--levels 1 5 10] [--set dynamics.workers=2] [--validate]
        [--compare dynamics.contact_model=edges] [--no-brute-force]

Timings are wall-clock on whatever else the machine is running (the load average is printed).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.phi.autodiff import AutoDiffPhi
from drake_clutter.phi.colouring import dense_jacobians
from drake_clutter.phi.derivatives import PhiDynamics
from drake_clutter.phi.dynamics import ARM_NODE, initial_state, make_spec
from drake_clutter.phi.engines import build_phi
from drake_clutter.phi.pruning import make_pruned_spec
from drake_clutter.phi.state import NU, scene_box_states
from drake_clutter.phi.workers import WorkerPool
from drake_clutter.scene.generators import generate_scene
from drake_clutter.testing.reach_paths import straight_reach


def _timed(fn, *args):
    tic = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - tic


def _brute_force(scene, path, config, world, knot_time):
    """Full-scene phi: per-knot step times, and one real dense Jacobian (middle knot)."""
    spec = make_spec(scene, [b.name for b in scene.boxes], knot_time=knot_time, config=config,
                     world=world)
    phi = build_phi(spec)
    x = phi.settle(initial_state(spec.layout, path[0], scene_box_states(scene)))
    xs, times = [x], []
    for u in path[1:]:
        x, dt = _timed(phi.step, x, u)
        xs.append(x)
        times.append(dt)
    columns = spec.layout.ndx + NU + 1
    mid = len(times) // 2
    _, dense = _timed(dense_jacobians, phi, xs[mid], path[mid + 1], config.fd_step)
    return {"columns": columns, "step": float(np.mean(times)),
            "horizon": columns * float(np.sum(times)),
            "dense_mid": dense, "dense_mid_estimate": columns * times[mid]}


def _ours(scene, path, config, world, knot_time, pool):
    tic = time.perf_counter()
    spec, report = make_pruned_spec(scene, path, knot_time=knot_time, config=config,
                                    world_config=world)
    prune_time = time.perf_counter() - tic
    serial = PhiDynamics(dataclasses.replace(spec, config=dataclasses.replace(config, workers=0)))
    x0 = serial.phi.settle(initial_state(spec.layout, path[0], scene_box_states(scene)))
    xs, rollout = _timed(serial.rollout, x0, path[1:])
    _, t_serial = _timed(serial.linearize_tangent, xs, path[1:])
    stats = serial.stats
    row = {"kept": len(report.kept), "added": len(report.added), "prune": prune_time,
           "step": rollout / len(path[1:]), "evals": stats.mean_evaluations,
           "evals_max": max(stats.evaluations, default=0), "known": stats.known_boxes,
           "autodiff": stats.autodiff_knots,
           "serial": t_serial, "parallel": float("nan"), "parallel_again": float("nan")}
    if pool is not None:
        pool.warm_up(spec)
        parallel = PhiDynamics(spec, pool=pool)
        parallel.rollout(x0, path[1:])  # traced in the parent, as in iLQR's forward pass
        _, row["parallel"] = _timed(parallel.linearize_tangent, xs, path[1:])
        parallel._last = None  # time the known-block reuse of a second call, not its cache
        _, row["parallel_again"] = _timed(parallel.linearize_tangent, xs, path[1:])
    return row


def run_levels(levels, seed, configs, knot_time, num_knots, pool, brute_force=True) -> None:
    """One row per level and configuration; ``configs`` is a list of (label, Config)."""
    print(f"{'config':>8} {'boxes':>5} {'kept':>4} {'step ms':>8} {'evals/knot':>10} "
          f"{'AD knots':>8} {'brute':>5} "
          f"{'serial s':>8} {'par s':>6} {'par2 s':>6} {'brute s':>8} {'x serial':>8} "
          f"{'x par':>6} {'dense(mid) s meas/est':>22} {'prune s':>7}")
    nan = float("nan")
    for n in levels:
        scene = generate_scene("bookshelf", n, seed=seed)
        path = straight_reach(scene, num_knots=num_knots)
        if path is None:
            print(f"{n:5d}  IK failed for the straight reach; skipped")
            continue
        for label, config in configs:
            config, world = config.dynamics, config.world
            ours = _ours(scene, path, config, world, knot_time, pool)
            brute = (_brute_force(scene, path, config, world, knot_time) if brute_force else
                     {"columns": 0, "horizon": nan, "dense_mid": nan, "dense_mid_estimate": nan})
            best = np.nanmin([ours["serial"], ours["parallel"]])
            print(f"{label:>8} {n:5d} {ours['kept']:4d} {1000 * ours['step']:8.1f} "
                  f"{ours['evals']:6.1f}/{ours['evals_max']:<3d} {ours['autodiff']:8d} "
                  f"{brute['columns']:5d} "
                  f"{ours['serial']:8.2f} {ours['parallel']:6.2f} {ours['parallel_again']:6.2f} "
                  f"{brute['horizon']:8.1f} {brute['horizon'] / ours['serial']:8.1f} "
                  f"{brute['horizon'] / best:6.1f} "
                  f"{brute['dense_mid']:10.1f}/{brute['dense_mid_estimate']:<10.1f} "
                  f"{ours['prune']:7.2f}", flush=True)


def validate(config, world, knot_time, num_knots, seed) -> None:
    """FD (two steps) vs AutoDiffXd over a whole reach on phi as configured (its "point"
    contact model, which AutoDiffXd cannot step, is replaced by "spheres")."""
    scene = generate_scene("bookshelf", 10, seed=seed)
    path = straight_reach(scene, num_knots=num_knots)
    model = "spheres" if config.contact_model == "point" else config.contact_model
    base = dataclasses.replace(config, contact_model=model, workers=0, derivative_method="fd")
    spec, report = make_pruned_spec(scene, path, knot_time=knot_time, config=base,
                                    world_config=world)
    print(f"\nFD vs AutoDiffXd, {model} phi, bookshelf 10 boxes seed {seed}, "
          f"{report.summary()}")
    for step in sorted({1e-6, config.fd_step}):
        dyn = PhiDynamics(dataclasses.replace(spec, config=dataclasses.replace(base,
                                                                               fd_step=step)))
        x0 = dyn.phi.settle(initial_state(spec.layout, path[0], scene_box_states(scene)))
        xs = dyn.rollout(x0, path[1:])
        (A, B), t_fd = _timed(dyn.linearize_tangent, xs, path[1:])
        autodiff = AutoDiffPhi(dyn.phi)
        free, contact, medians, t_ad = [], [], [], 0.0
        for t in range(len(path) - 1):
            (Aa, Ba), dt = _timed(autodiff.jacobians, xs[t], path[t + 1])
            t_ad += dt
            J, Ja = np.hstack([A[t], B[t]]), np.hstack([Aa, Ba])
            big = np.abs(Ja) > 1e-6 * np.abs(Ja).max()
            medians.append(np.median(np.abs(J - Ja)[big] / np.abs(Ja)[big]))
            rel = np.linalg.norm(J - Ja) / np.linalg.norm(Ja)
            edges = dyn.phi.step_traced(xs[t], path[t + 1])[1]
            (contact if any(ARM_NODE in e for e in edges) else free).append(rel)
        contact = np.array(contact) if contact else np.array([np.nan])
        free = np.array(free) if free else np.array([np.nan])
        print(f"  fd_step {step:g}: entry-wise relative error median {np.median(medians):.1e} "
              f"(worst knot {np.max(medians):.1e}); whole-Jacobian relative error: "
              f"{len(free)} free knots median {np.median(free):.1e} max {np.max(free):.1e}, "
              f"{len(contact)} arm-contact knots median {np.median(contact):.1e}, "
              f"{np.mean(contact < 1e-3):.0%} below 1e-3; time FD {t_fd:.1f} s, "
              f"AutoDiffXd {t_ad:.1f} s")


def main(argv=None) -> int:
    """Runs the benchmark; prints one row per clutter level."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=int, nargs="+", default=[1, 5, 10, 15, 20, 25])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--config")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--validate", action="store_true")
    parser.add_argument("--compare", action="append", default=[], metavar="FIELD=VALUE")
    parser.add_argument("--no-brute-force", action="store_true")
    args = parser.parse_args(argv)
    config = load_config(args.config, args.overrides)
    configs = [("base", config)]
    if args.compare:
        configs.append(("compare", load_config(args.config, args.overrides + args.compare)))
    dyn, knot_time = config.dynamics, config.baseline.knot_time
    num_knots = config.baseline.num_knots
    print(f"load average at start {os.getloadavg()[0]:.2f} (2 cores); {num_knots} knots of "
          f"{knot_time} s, {dyn.substeps} SAP sub-steps each; contact {dyn.contact_model}, "
          f"fd_step {dyn.fd_step:g} {dyn.fd_scheme}, stride {dyn.derivative_stride}, "
          f"method {dyn.derivative_method} (AutoDiffXd from {dyn.autodiff_min_groups} groups), "
          f"workers {dyn.workers}")
    pool = WorkerPool(dyn.workers) if dyn.workers > 0 else None
    try:
        run_levels(args.levels, args.seed, configs, knot_time, num_knots, pool,
                   brute_force=not args.no_brute_force)
    finally:
        if pool is not None:
            pool.close()
    if args.validate:
        validate(dyn, config.world, knot_time, num_knots, args.seed)
    print(f"load average at end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
