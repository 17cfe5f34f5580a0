"""Where phi leaves a judged plan's boxes: the benchmarks comparing phi with the Bullet judge.

``phi_final`` rolls a plan out in phi with every box dynamic; ``classes`` sorts boxes as the
judge does (Sec. III: standing, tipped, fallen) from their final positions and tilts.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from drake_clutter.phi.dynamics import initial_state, make_spec
from drake_clutter.phi.engines import build_phi
from drake_clutter.phi.state import scene_box_states
from drake_clutter.scene.grading import off_the_board, tilt_angle


def classes(scene, p_WB: np.ndarray, tilts: np.ndarray, max_tilt: float) -> list[str]:
    """Sec. III's class per box from final positions (W, m) and tilts (rad)."""
    fallen = off_the_board(scene, p_WB)
    return ["fallen" if f else "tipped" if t > max_tilt else "standing"
            for f, t in zip(fallen, tilts, strict=True)]


class PhiFinal(NamedTuple):
    """Where phi leaves a plan's boxes, and the forces it saw on the way."""

    positions: np.ndarray  # (n, 3), W, m: the boxes' final positions
    tilts: np.ndarray  # (n,), rad: the boxes' final tilts
    seconds: float  # the rollout's wall-clock time, s
    arm_peak: float  # peak knot-mean contact force on the arm, N
    shelf_peak: float  # peak knot-mean shelf force on a box beyond its weight, N


def phi_final(scene, trajectory, config, settle: float, arm: str = "capsules",
              until: float | None = None) -> PhiFinal:
    """phi, its arm in geometry variant ``arm``, rolls the plan out with every box dynamic and
    holds the arm ``settle`` s: the boxes' final positions and tilts, the rollout's seconds,
    and over the plan's knots (up to ``until`` s plus one knot, if given) the peak knot-mean
    contact force on the arm and the peak knot-mean force of a box on the shelf beyond its
    weight (Sec. III's kinematic-failure measure, which the judge averages over 0.2 s)."""
    names = [b.name for b in scene.boxes]
    knot_time = float(np.diff(trajectory.times[:2])[0])
    spec = make_spec(scene, names, None, knot_time, config.dynamics, config.world, arm)
    phi = build_phi(spec)
    tic = time.perf_counter()
    x = phi.settle(initial_state(spec.layout, trajectory.q[0], scene_box_states(scene)))
    arm_peak, shelf_peak = 0.0, 0.0
    for t, u in zip(trajectory.times[1:], trajectory.q[1:], strict=True):
        if until is not None and t > until + knot_time:
            break
        x, f = phi.step_forces(x, u)
        arm_peak = max(arm_peak, float(np.nan_to_num(f[0])))
        excess = np.nan_to_num(phi.shelf_forces[1:] - phi.weights[1:])
        shelf_peak = max(shelf_peak, float(excess.max(initial=0.0)))
    x = phi.settle(x, settle)
    seconds = time.perf_counter() - tic
    boxes = spec.layout.boxes(x)
    R = Rotation.from_quat(np.nan_to_num(boxes[:, [1, 2, 3, 0]], nan=1.0)).as_matrix()
    return PhiFinal(boxes[:, 4:7], tilt_angle(R), seconds, arm_peak, shelf_peak)
