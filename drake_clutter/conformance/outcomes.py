"""What an engine's run of a scenario did to each box: the trace every engine returns, and the
engine-neutral reading of it (class, displacement, rise, the force on the static shelf).

Frames and units: W, metres, radians, seconds, newtons.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_clutter.conformance.scenarios import GRAVITY, Scenario

THROWN_DISTANCE = 0.5  # m: a box moved farther than this (or off the board) was thrown
UPRIGHT_FOR_RISE = 0.05  # rad: a box's rise is read only while it tilts less than this
FALLEN_DROP = 0.02  # m: a box whose centre is this far below its resting height left the board


@dataclass
class Trace:
    """An engine's run of a scenario, sampled every ``times`` step: box centres p_WB (T, n, 3),
    rotations R_WB (T, n, 3, 3), each box's summed contact force with the static shelf (board
    and walls, N, (T, n), its weight included) and the run's wall-clock seconds; ``failure``
    names a simulation failure (then the samples end where it happened). ``jam`` (phi only,
    m, (n,)) is phi's jam measure of each box over the run (`phi.jam`)."""

    engine: str
    times: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    static_force: np.ndarray
    seconds: float
    failure: str = ""
    jam: np.ndarray | None = None


@dataclass(frozen=True)
class BoxOutcome:
    """One box at the end of a run: ``kind`` "upright", "tipped" (tilt beyond ``max_tilt``) or
    "fallen" (off the board); ``moved`` m of its centre in the board's plane; ``tilt`` rad;
    ``rise`` m, the highest its centre rose while it stood (tilt < 0.05 rad); ``thrown`` when it
    fell or moved more than 0.5 m; ``squeeze`` N, its mean force on the static shelf beyond its
    weight over the last ``force_window`` s (Sec. III's kinematic-failure quantity); ``jam``
    m, phi's jam measure (NaN in the other engines)."""

    kind: str
    moved: float
    tilt: float
    rise: float
    thrown: bool
    squeeze: float
    jam: float = float("nan")


def tilts(rotations: np.ndarray) -> np.ndarray:
    """Angle between each box's z axis and W's z (rad), any leading shape."""
    return np.arccos(np.clip(rotations[..., 2, 2], -1.0, 1.0))


def box_outcomes(scenario: Scenario, trace: Trace, max_tilt: float,
                 force_window: float) -> list[BoxOutcome]:
    """The outcome of every box of ``scenario`` in ``trace`` (scenario order); a failed run's
    boxes read "failed" with NaN numbers."""
    if trace.failure or not len(trace.times):
        nan = float("nan")
        return [BoxOutcome("failed", nan, nan, nan, False, nan) for _ in scenario.boxes]
    out = []
    window = trace.times >= trace.times[-1] - force_window
    for i, box in enumerate(scenario.boxes):
        p, tilt = trace.positions[:, i], tilts(trace.rotations[:, i])
        rest_z = scenario.box_z(box)
        moved = float(np.linalg.norm(p[-1, :2] - np.asarray(box.xy)))
        fallen = p[-1, 2] < scenario.shelf.top_height + min(box.size) / 2 - FALLEN_DROP
        kind = "fallen" if fallen else ("tipped" if tilt[-1] > max_tilt else "upright")
        standing = tilt < UPRIGHT_FOR_RISE
        rise = float(np.max(p[standing, 2] - rest_z)) if np.any(standing) else 0.0
        weight = box.mass * GRAVITY
        squeeze = float(np.mean(trace.static_force[window, i]) - weight)
        jam = float(trace.jam[i]) if trace.jam is not None else float("nan")
        out.append(BoxOutcome(kind, moved, float(tilt[-1]), max(rise, 0.0),
                              bool(fallen or moved > THROWN_DISTANCE), squeeze, jam))
    return out


def realised_friction(scenario: Scenario, trace: Trace) -> float:
    """A drag's box-board coefficient: twice the quadratic coefficient of the box's path along
    the launch, fitted from 0.02 s (after the first contact's transient) until its speed first
    falls below 20 % of the launch speed, over g (a least-squares fit, robust to the chatter of
    soft contact). NaN without enough samples."""
    v0 = float(np.linalg.norm(scenario.boxes[0].velocity))
    direction = np.asarray(scenario.boxes[0].velocity) / v0
    x = trace.positions[:, 0, :] @ direction
    speed = np.diff(x) / np.diff(trace.times)
    slow = np.flatnonzero(speed < 0.2 * v0)
    end = slow[0] + 1 if len(slow) else len(x)
    window = np.arange(len(x)) < end
    window &= trace.times >= 0.02
    if np.count_nonzero(window) < 4:
        return float("nan")
    curvature = np.polyfit(trace.times[window], x[window], 2)[0]
    return float(-2.0 * curvature / GRAVITY)


def knot_jam(approach: list[np.ndarray], per_knot: int, num_boxes: int) -> np.ndarray:
    """phi's jam measure per box over a scripted run (m): the largest sum of the recorded
    approach (one (num_boxes,) row per reading) over ``per_knot`` readings in a row - one
    knot's worth (a scripted run has no knots; `Phi.step_jam` sums within each knot, so it
    reads at most this)."""
    if not approach:
        return np.zeros(num_boxes)
    steps = np.array(approach)
    sums = np.cumsum(np.vstack([np.zeros(num_boxes), steps]), axis=0)
    return (sums[per_knot:] - sums[:-per_knot]).max(axis=0) if len(steps) >= per_knot \
        else sums[-1]


def phi_trace(samples: tuple[list, list, list], forces: list[np.ndarray], num_boxes: int,
              seconds: float, failure: str, jam: np.ndarray) -> Trace:
    """phi's `Trace` from a harness's samples (times s, centres (n, 3), rotations (n, 3, 3), the
    first at t = 0) and one static-force reading (N, (n,)) per step after it; the t = 0 sample
    repeats the first reading, and a failed run keeps as many readings as samples."""
    times, positions, rotations = samples
    forces = [forces[0] if forces else np.zeros(num_boxes)] + forces
    n = len(times)
    return Trace("phi", np.array(times), np.array(positions), np.array(rotations),
                 np.array(forces[:n]), seconds, failure, jam)
