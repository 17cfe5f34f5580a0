"""Where phi leaves a judged plan's boxes: the benchmarks comparing phi with the Bullet judge.

``phi_final`` rolls a plan out in phi with every box dynamic; ``classes`` sorts boxes as the
judge does (Sec. III: standing, tipped, fallen) from their final positions and tilts.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.spatial.transform import Rotation

from drake_clutter.evaluation.judge import off_the_board, tilt_angle
from drake_clutter.phi.dynamics import Phi, initial_state, make_spec, scene_box_states


def classes(scene, p_WB: np.ndarray, tilts: np.ndarray, max_tilt: float) -> list[str]:
    """Sec. III's class per box from final positions (W, m) and tilts (rad)."""
    fallen = off_the_board(scene, p_WB)
    return ["fallen" if f else "tipped" if t > max_tilt else "standing"
            for f, t in zip(fallen, tilts, strict=True)]


def phi_final(scene, trajectory, config, settle: float, arm: str = "capsules",
              until: float | None = None) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Box positions (n, 3, W, m) and tilts (n, rad) after phi, its arm in geometry variant
    ``arm``, rolls the plan out with every box dynamic and holds the arm ``settle`` s; the
    rollout's seconds; and the peak knot-mean contact force on the arm (N) over the plan, or
    over its knots up to ``until`` s plus one knot."""
    names = [b.name for b in scene.boxes]
    knot_time = float(np.diff(trajectory.times[:2])[0])
    spec = make_spec(scene, names, None, knot_time, config.dynamics, config.world, arm)
    phi = Phi(spec)
    tic = time.perf_counter()
    x = phi.settle(initial_state(spec.layout, trajectory.q[0], scene_box_states(scene)))
    peak = 0.0
    for t, u in zip(trajectory.times[1:], trajectory.q[1:], strict=True):
        if until is not None and t > until + knot_time:
            break
        x, f = phi.step_forces(x, u)
        peak = max(peak, float(np.nan_to_num(f[0])))
    x = phi.settle(x, settle)
    seconds = time.perf_counter() - tic
    boxes = spec.layout.boxes(x)
    R = Rotation.from_quat(np.nan_to_num(boxes[:, [1, 2, 3, 0]], nan=1.0)).as_matrix()
    return boxes[:, 4:7], tilt_angle(R), seconds, peak
