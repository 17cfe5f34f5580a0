"""One push action of the rearrange planner as a joint path, and its geometric checks.

A move pushes box B along a horizontal unit direction u by ``travel`` (m). Its path, from and
back to the reach's first configuration q0 (outside the shelf), moves the tool frame G with the
pre-grasp's orientation (its axis tipped down by ``push_pitch``, turned to in place at q0's G
at ``turn_speed``; where every tilted path is refused, untilted) and the gripper closed
through:

1. the portal in: G at the pre-contact point's height and side, as far out as q0's G;
2. the pre-contact point: B's centre at ``push_height`` of its height, backed off along -u by
   B's half extent along u and ``standoff`` and by the closed gripper's own gap to B there;
   with ``push_low`` that height is tried first and G's height at the pre-grasp (where the
   reach clears the board) next, else only the higher of the two; never above B's top
   less 1 cm;
3. the push: along u by that gap plus ``travel``, at ``push_speed``;
4. the retreat: back along -u by ``retreat``, then out along the approach to the portal;
5. q0 again, the joints interpolated.

Knots are ``baseline.knot_time`` apart; G moves at ``tool_speed`` except while it pushes. The
joints follow G knot by knot (`tool_path.follow_chain`). The path is refused (None, with the
reason) where G misses its targets, the knots leave the judge's joint or speed limits, or the
arm enters a box it does not push by more than ``entry_tolerance`` on the way in or out
(boxes at the board's poses before the move; after it on the way out). A refused path names
the boxes that blocked it (`Blocked`: a box not pushed, entered too deep on the way in, while
pushing or on the way out where that box stays put) with the knots that entered it, so a
search can push that box out of the way first.
Frames: W; metres, seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from drake_clutter.common.config import Config
from drake_clutter.planners.clearance import ShelfClearance, dense_check
from drake_clutter.planners.geometry import ArmGeometry
from drake_clutter.planners.rearrange.board import Offsets, box_distance, entered, world_poses
from drake_clutter.planners.tool_path import ARM, ApproachFrame, follow_chain
from drake_clutter.robot import pr2
from drake_clutter.scene.mechanics import G, chain_tip_ratio
from drake_clutter.scene.shelf import SHELF_FRICTION
from drake_clutter.trajectory import Trajectory, plan_limit_violation

POSE_LIMIT = 1e-3  # m or rad: an action whose knots miss their G targets by more is refused
CLOSED = 0.0  # m: the gripper's opening while it pushes
GAP_REACH = 1.0  # m: the farthest gripper-to-box gap measured before a push


@dataclass(frozen=True)
class Move:
    """One push: ``box`` along ``u`` (2,) by ``travel`` (m); ``moved``: every box it moves on
    the board (the chain, ``box`` first); ``tip_ratio``: quasi-static mechanics' tipping
    ratio of the pushed box (`push_tip_ratio`; above 1 it tips; 0 where not computed)."""

    box: str
    u: tuple[float, float]
    travel: float
    moved: tuple[str, ...]
    tip_ratio: float = 0.0

    def to_data(self) -> dict:
        """JSON-ready dict."""
        return {"box": self.box, "u": list(self.u), "travel": self.travel,
                "moved": list(self.moved), "tip_ratio": self.tip_ratio}


@dataclass(frozen=True)
class Blocked:
    """A box other than the target and the pushed ones that a refused action's arm entered
    by more than ``entry_tolerance``, and the knots (K, 8) of the part of the path (the way
    in, the push or the way out) that entered it."""

    box: str
    knots: np.ndarray


def push_tip_ratio(geometry: ArmGeometry, board_poses: dict, move: Move, grasp_z: float,
                   config: Config) -> float:
    """`mechanics.chain_tip_ratio` of ``move``'s pushed box (boxes at ``board_poses``, X_WB)
    pushed at the first pre-contact point `contact_points` tries (G's height), its length
    along the push, the judge's pair coefficients (`SHELF_FRICTION` x the box's), the boxes
    it shoves ahead (``move.moved[1:]``) a load of their board friction pressing back at half
    the lowest of their heights and its own."""
    boxes = {b.name: b for b in geometry.scene.boxes}
    box, X = boxes[move.box], board_poses[move.box]
    u = np.array([move.u[0], move.u[1], 0.0])
    along = float(np.abs(X.rotation().matrix().T @ u) @ (np.asarray(box.size) / 2.0))
    bottom = X.translation()[2] - box.size[2] / 2.0
    z = float(contact_points(geometry, board_poses, move, grasp_z, config)[0][2]) - bottom
    mu = box.friction * SHELF_FRICTION
    ahead = [boxes[n] for n in move.moved[1:]]
    load = sum(b.friction * SHELF_FRICTION * b.mass * G for b in ahead)
    load_z = min([box.size[2], *(b.size[2] for b in ahead)]) / 2.0
    return float(chain_tip_ratio(2.0 * along, z, mu, mu, box.mass, load, load_z))


def _segment(a: np.ndarray, b: np.ndarray, speed: float, knot_time: float) -> np.ndarray:
    """G targets (K, 3) from ``a`` (excluded) to ``b`` (included) at ``speed`` (m/s)."""
    knots = max(1, int(np.ceil(np.linalg.norm(b - a) / (speed * knot_time))))
    return a + np.outer(np.arange(1, knots + 1) / knots, b - a)


def contact_points(geometry: ArmGeometry, board_poses: dict, move: Move, grasp_z: float,
                   config: Config) -> list[np.ndarray]:
    """G's pre-contact points (3,) in W to try in order (module docstring, step 2), before the
    gripper's gap: at ``push_height`` of the box's height, then at ``grasp_z`` (m, G's height
    at the pre-grasp, where the reach clears the board) where that is higher by 1 mm or more;
    without ``push_low`` only the higher; none above the box's top less 1 cm."""
    box = next(b for b in geometry.scene.boxes if b.name == move.box)
    X = board_poses[move.box]
    u = np.array([move.u[0], move.u[1], 0.0])
    half = np.asarray(box.size) / 2.0
    along = float(np.abs(X.rotation().matrix().T @ u) @ half)
    centre = X.translation()
    top = centre[2] + half[2] - 0.01
    low = min(centre[2] - half[2] + config.rearrange.push_height * box.size[2], top)
    high = min(max(low, grasp_z), top)
    heights = [low, high] if config.rearrange.push_low and high - low >= 1e-3 else [high]
    p = centre - (along + config.rearrange.standoff) * u
    return [np.array([p[0], p[1], z]) for z in heights]


def push_rotation(rotation: np.ndarray, pitch: float) -> np.ndarray:
    """G's rotation (3, 3, W) while it pushes: the pre-grasp's ``rotation`` turned about the
    horizontal axis across G's x-axis (where the gripper points) so that x tips down by
    ``pitch`` (rad); ``rotation`` itself where pitch is 0 or x is vertical."""
    axis = np.cross(rotation[:, 0], [0.0, 0.0, 1.0])
    if pitch == 0.0 or np.linalg.norm(axis) < 1e-9:
        return rotation
    turn = Rotation.from_rotvec(-pitch * axis / np.linalg.norm(axis))
    return turn.as_matrix() @ rotation


def turning(rotation: np.ndarray, turned: np.ndarray, speed: float,
            knot_time: float) -> np.ndarray:
    """G's rotations (K, 3, 3) from ``rotation`` (excluded) to ``turned`` (included) at
    ``speed`` (rad/s), slerped; none (0, 3, 3) where they are the same."""
    pair = Rotation.from_matrix(np.stack([rotation, turned]))
    angle = float((pair[0].inv() * pair[1]).magnitude())
    knots = int(np.ceil(angle / (speed * knot_time))) if angle > 1e-9 else 0
    return Slerp([0.0, 1.0], pair)(np.arange(1, knots + 1) / max(knots, 1)).as_matrix()


def action_path(geometry: ArmGeometry, clearance: ShelfClearance, frame: ApproachFrame,
                q0: np.ndarray, rotation: np.ndarray, before: Offsets, after: Offsets,
                move: Move, config: Config, blocked: list[Blocked] | None = None
                ) -> tuple[np.ndarray | None, str]:
    """The knots (K, 8) of ``move`` from q0 back to q0 (module docstring), the board at
    ``before`` and ``after`` the move, G at the pre-grasp's ``rotation`` (3, 3) tipped down by
    ``rearrange.push_pitch`` (`push_rotation`, turned to in front of the shelf) and, where
    that is refused, untilted: the first that is not refused at the tilts, contact heights and
    ways in in order; (None, why) where refused: the reasons of each tried, and each box that
    blocked a way appended to ``blocked`` where given. The path clears the shelf
    (`clearance.dense_check`)."""
    poses = world_poses(geometry, before)
    tilted = push_rotation(rotation, config.rearrange.push_pitch)
    reasons: list[str] = []
    found: list[Blocked] = []
    for pushing in [tilted] + ([rotation] if tilted is not rotation else []):
        turns = turning(rotation, pushing, config.rearrange.turn_speed,
                        config.baseline.knot_time)
        for p0 in contact_points(geometry, poses, move, float(frame.positions[-1][2]), config):
            for way in ("direct", "corridor"):
                path, why, by = _one_way(geometry, clearance, frame, q0, turns, pushing, poses,
                                         after, move, p0, way, config)
                if path is not None:
                    return path, ""
                reasons.append(why)
                found += [by] if by is not None else []
    if blocked is not None:
        blocked += found
    return None, "; ".join(reasons)


def _one_way(geometry: ArmGeometry, clearance: ShelfClearance, frame: ApproachFrame,
             q0: np.ndarray, turns: np.ndarray, pushing: np.ndarray, poses: dict,
             after: Offsets, move: Move, p0: np.ndarray, way: str, config: Config
             ) -> tuple[np.ndarray | None, str, Blocked | None]:
    """The action's knots (K, 8) through one way in (`_way_in`) to the pre-contact point
    ``p0`` (3,) with G at ``pushing`` (3, 3) after ``turns``, or (None, why, the box that
    blocked it or None)."""
    q_in, gap, why, by = _way_in(geometry, frame, q0, turns, pushing, poses, move, p0, way,
                                 config)
    if q_in is None:
        return None, why, by
    path, why, by = _push_and_out(geometry, frame, q0, q_in, gap, poses, after, move, pushing,
                                  config)
    why = why or _outside_limits(path, config)
    if path is not None and not why and dense_check(clearance, path[:, :ARM],
                                                    config.baseline).passed:
        return path, "", None
    return None, why or f"the arm meets the shelf ({way} way in)", by


def _outside_limits(path: np.ndarray | None, config: Config) -> str:
    """Why the knots ``path`` (K, 8; None: nothing to check) leave the judge's joint and speed
    limits (`trajectory.plan_limit_violation`), or ''."""
    if path is None:
        return ""
    times = np.arange(len(path)) * config.baseline.knot_time
    violation = plan_limit_violation(Trajectory(times, path), config.evaluation)
    return f"the path leaves the judge's limits: {violation}" if violation else ""


def _way_in(geometry: ArmGeometry, frame: ApproachFrame, q0: np.ndarray, turns: np.ndarray,
            rotation: np.ndarray, poses: dict, move: Move, p0: np.ndarray, way: str,
            config: Config) -> tuple[np.ndarray | None, float, str, Blocked | None]:
    """The knots from q0 (excluded) to the pre-contact point ``p0`` (3,), G first turned in
    place through ``turns`` (K, 3, 3) to ``rotation`` (3, 3), then: "direct" (out in
    front of the shelf to ``p0``'s side and height, then in along the approach) or
    "corridor" (along the reach's own G path to ``p0``'s depth, then across to it); backed
    off along -u once where the closed gripper already touches the box there. Also the
    closed gripper's gap to the box at the last knot (m); (None, nan, why, the box that
    blocked it or None) where refused."""
    cfg, dt = config.rearrange, config.baseline.knot_time
    start = frame.positions[0]
    u = np.array([move.u[0], move.u[1], 0.0])
    for _ in range(2):
        if way == "direct":
            portal = p0 + float((start - p0) @ frame.d) * np.r_[frame.d[:2], 0.0]
            targets = np.vstack([_segment(start, portal, cfg.tool_speed, dt),
                                 _segment(portal, p0, cfg.tool_speed, dt)])
        else:
            depth = float((p0 - frame.positions[-1]) @ frame.d)
            past = np.flatnonzero(frame.along > depth + 1e-9)
            ahead = frame.positions[:max(1, past[0] if past.size else len(frame.along))]
            corner = ahead[-1]
            targets = np.vstack([_path_at_speed(ahead, cfg.tool_speed, dt),
                                 _segment(corner, p0, cfg.tool_speed, dt)])
        targets = np.vstack([np.repeat(start[None], len(turns), axis=0), targets])
        rotations = np.concatenate([turns, np.broadcast_to(rotation, (len(targets) - len(turns),
                                                                      3, 3))])
        q_in, error = follow_chain(geometry, q0, targets, rotations,
                                   np.full(len(targets), CLOSED))
        if error > POSE_LIMIT:
            return None, np.nan, f"G misses the {way} way in by {error * 1e3:.1f} mm", None
        gap = box_distance(geometry, q_in[-1], poses, move.box, GAP_REACH)
        if gap >= 0.0:
            break
        p0 = p0 - (cfg.standoff - gap) * u
    else:
        return (None, np.nan, f"the gripper touches {move.box} before the push ({way} way in)",
                None)
    why, by = _entries(geometry, q_in, poses, frozenset(move.moved), config, f"{way} in")
    return (None, np.nan, why, by) if why else (q_in, gap, "", None)


def _path_at_speed(points: np.ndarray, speed: float, knot_time: float) -> np.ndarray:
    """G targets along the polyline ``points`` (N, 3) from its first point (excluded) at
    ``speed`` (m/s)."""
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:], strict=True):
        if np.linalg.norm(b - a) > 1e-9:
            out.append(_segment(a, b, speed, knot_time))
    return np.vstack(out)[1:] if len(out) > 1 else points[:1]


def _push_and_out(geometry: ArmGeometry, frame: ApproachFrame, q0: np.ndarray,
                  q_in: np.ndarray, gap: float, poses: dict, after: Offsets, move: Move,
                  rotation: np.ndarray, config: Config
                  ) -> tuple[np.ndarray | None, str, Blocked | None]:
    """The whole action from the way in ``q_in`` (the gripper ``gap`` m from the box at its
    end): the push, the retreat, q0 again; where refused (None, why, the box that blocked it
    where one did and stays put)."""
    cfg, dt = config.rearrange, config.baseline.knot_time
    start = frame.positions[0]
    u = np.array([move.u[0], move.u[1], 0.0])
    p0 = geometry.tool_jacobian(q_in[-1])[0].translation()
    p1 = p0 + (gap + move.travel) * u
    p2 = p1 - cfg.retreat * u
    out = p2 + float((start - p2) @ frame.d) * np.r_[frame.d[:2], 0.0]
    pushing = _segment(p0, p1, cfg.push_speed, dt)
    way_out = np.vstack([_segment(p1, p2, cfg.tool_speed, dt),
                         _segment(p2, out, cfg.tool_speed, dt)])
    rest, error = follow_chain(geometry, q_in[-1], np.vstack([pushing, way_out]), rotation,
                               np.full(len(pushing) + len(way_out), CLOSED))
    if error > POSE_LIMIT:
        return None, f"G misses the push or the way out by {error * 1e3:.1f} mm", None
    why, by = _entries(geometry, rest[:len(pushing)], poses, frozenset(move.moved),
                       config, "pushing")
    if not why:
        why, by = _entries(geometry, rest[len(pushing):], world_poses(geometry, after),
                           frozenset(), config, "out")
        by = None if by is None or by.box in move.moved else by
    if why:
        return None, why, by
    path = np.vstack([q0[None], q_in, rest, _home(rest[-1], q0, config)])
    path[0, ARM] = CLOSED
    return path, "", None


def _entries(geometry: ArmGeometry, q: np.ndarray, poses: dict, skip: frozenset[str],
             config: Config, where: str) -> tuple[str, Blocked | None]:
    """Why the arm at the knots ``q`` enters a box not in ``skip`` by more than
    ``rearrange.entry_tolerance``, or the target by more than ``target_tolerance`` (m), and
    that box with ``q`` where it is not the target; ('', None) where it does not."""
    target, cfg = geometry.scene.target, config.rearrange
    for row in q:
        for name, depth in entered(geometry, row, poses, skip).items():
            if depth > (cfg.target_tolerance if name == target else cfg.entry_tolerance):
                why = f"the arm enters {name} by {depth * 1e3:.0f} mm on the way {where}"
                return why, (None if name == target else Blocked(name, np.array(q)))
    return "", None


def _home(q_from: np.ndarray, q0: np.ndarray, config: Config) -> np.ndarray:
    """Knots from ``q_from`` (excluded) to ``q0`` (included), joints linear, at most half the
    judge's joint speed limit per knot; the gripper stays closed."""
    speeds = pr2.velocity_limits()
    limit = 0.5 * np.array([speeds[j] for j in pr2.ARM_JOINTS]) * config.baseline.knot_time
    knots = max(1, int(np.ceil(np.max(np.abs(q0[:ARM] - q_from[:ARM]) / limit))))
    s = np.arange(1, knots + 1)[:, None] / knots
    path = q_from + s * (q0 - q_from)
    path[:, ARM] = CLOSED
    return path
