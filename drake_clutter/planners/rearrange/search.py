"""Which boxes to push, where, and in what order: a beam search on the board, geometry first.

A state is the board after some moves (`board.Board` offsets) with the moves' joint paths. Its
crowd is the boxes other than the target that the region to clear (`board.reach_region`)
enters by more than ``rearrange.deep``. A state is expanded by pushing one of its crowding
boxes (each of them: the orderings are searched, not fixed) along each of
``rearrange.directions`` horizontal directions (none pointing back toward the robot by more
than ``pull_limit``) just far enough that it leaves the region, plus ``travel_margin``; the
boxes it meets are shoved ahead (``chain``). Children are ranked by how many boxes still crowd
the region, then (``rearrange.tipping`` "rank") by their pushes that quasi-static mechanics
says tip the pushed box (`actions.push_tip_ratio` above 1; "refuse": those pushes are left
out), then by the boxes' total travel; the best ``beam_width`` whose push action has a
path (`actions.action_path`: reachable, off the other boxes) are kept per depth, up to
``max_moves`` moves. With ``rearrange.clear_ways`` a push refused because its arm enters
another box (`actions.Blocked`) also proposes a detour: that box pushed out of the refused
knots' way first (Dogar & Srinivasa's recursion: what blocks an action is cleared before
it), ranked after the pushes that cleared, so the blocked push can be tried again from it
at the next depth. A state with no crowd is a goal; the search stops with ``sequences``
goals, at the last depth, or when the deadline passes. Deterministic: same scene and reach,
same goals. Frames: W; metres.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.planners.budget import Deadline
from drake_clutter.planners.clearance import ShelfClearance
from drake_clutter.planners.geometry import ArmGeometry
from drake_clutter.planners.rearrange.actions import (
    Blocked,
    Move,
    action_path,
    push_tip_ratio,
)
from drake_clutter.planners.rearrange.board import (
    Board,
    Offsets,
    box_distance,
    crowding,
    moved_boxes,
    world_poses,
)
from drake_clutter.planners.tool_path import ApproachFrame


@dataclass(frozen=True)
class State:
    """The board after ``moves`` (their knot paths ``paths``), the boxes' total travel (m),
    the boxes still crowding the region (name -> depth, m) and the board before the last
    move."""

    offsets: Offsets
    moves: tuple[Move, ...] = ()
    paths: tuple[np.ndarray, ...] = ()
    travel: float = 0.0
    crowd: dict[str, float] = field(default_factory=dict)
    previous: Offsets = field(default_factory=dict)
    tips: int = 0

    def key(self) -> tuple[int, float]:
        """Rank among states, best first: fewer boxes crowding, then less travel."""
        return (len(self.crowd), self.travel)

    def tip_key(self) -> tuple[int, int, float]:
        """`key` with the moves mechanics says tip their box (``tips``) after the crowd."""
        return (len(self.crowd), self.tips, self.travel)


def ranking(config: Config):
    """The key states are ranked by: `State.tip_key` with ``rearrange.tipping`` "rank", else
    `State.key`."""
    return State.tip_key if config.rearrange.tipping == "rank" else State.key


@dataclass
class RoomSearch:
    """The goals found (states with room), and counts: states expanded, pushes the board
    allowed, actions refused by their paths (with the first reasons), and the deepest depth."""

    goals: list[State] = field(default_factory=list)
    expanded: int = 0
    pushes: int = 0
    refused: int = 0
    reasons: list[str] = field(default_factory=list)
    depth: int = 0
    tipping: int = 0
    detours: int = 0

    def to_data(self) -> dict:
        """JSON-ready summary (the goals' moves, not their paths; ``tipping``: the pushes
        left out because mechanics says they tip their box; ``detours``: the pushes of a
        blocking box proposed)."""
        return {"goals": [[m.to_data() for m in g.moves] for g in self.goals],
                "expanded": self.expanded, "pushes": self.pushes, "refused": self.refused,
                "reasons": self.reasons[:5], "depth": self.depth, "tipping": self.tipping,
                "detours": self.detours}


def directions(frame: ApproachFrame, count: int, pull_limit: float) -> list[np.ndarray]:
    """``count`` horizontal unit directions (2,) evenly spread from the approach direction,
    those pointing back toward the robot (cosine with it below -``pull_limit``) left out."""
    d = frame.d[:2] / np.linalg.norm(frame.d[:2])
    base = np.arctan2(d[1], d[0])
    out = []
    for angle in base + np.linspace(0.0, 2 * np.pi, count, endpoint=False):
        u = np.array([np.cos(angle), np.sin(angle)])
        if u @ d >= -pull_limit:
            out.append(u)
    return out


def _distances(geometry: ArmGeometry, region: np.ndarray, offsets: Offsets, box: str,
               reach: float) -> np.ndarray:
    """The region's arm's signed distance (m) to ``box`` at each knot (``reach`` where farther)."""
    poses = world_poses(geometry, offsets)
    return np.array([box_distance(geometry, q, poses, box, reach) for q in region])


def clearing_push(geometry: ArmGeometry, board: Board, region: np.ndarray, offsets: Offsets,
                  box: str, u: np.ndarray, config: Config) -> tuple[Offsets, float] | None:
    """The board after ``box`` is pushed along ``u`` (2,) until the region's arm enters it by
    at most ``deep``, plus ``travel_margin``, and that travel (m); None where the board blocks
    the push first (the target, a wall, the board's edge, a chain too long) or it takes more
    than ``max_travel``."""
    cfg = config.rearrange
    d0 = _distances(geometry, region, offsets, box, cfg.max_travel + 0.05)
    for travel in np.arange(cfg.step, cfg.max_travel + 1e-9, cfg.step):
        new = board.push(offsets, box, travel * u)
        if new is None:
            return None
        near = region[d0 < -cfg.deep + travel]  # no other knot can still be entered
        if box not in crowding(geometry, near, new, cfg.deep):
            final = board.push(offsets, box, (travel + cfg.travel_margin) * u)
            return (final, travel + cfg.travel_margin) if final is not None else (new, travel)
    return None


def children(geometry: ArmGeometry, board: Board, region: np.ndarray, state: State,
             frame: ApproachFrame, config: Config, found: RoomSearch) -> list[State]:
    """Every push of a crowding box of ``state`` that clears it (module docstring), ranked,
    without its path yet."""
    out = []
    for box in sorted(state.crowd, key=lambda b: (-state.crowd[b], b)):
        out += _pushes(geometry, board, region, region, state, box, frame, config, found)
    return sorted(out, key=ranking(config))


def detours(geometry: ArmGeometry, board: Board, region: np.ndarray, state: State,
            blocked: Blocked, frame: ApproachFrame, config: Config, found: RoomSearch
            ) -> list[State]:
    """Every push of ``blocked.box`` from ``state`` that takes it out of the blocked knots'
    way (entered by at most ``deep``), ranked, without its path yet; the crowd is read on
    ``region`` as for any push."""
    out = _pushes(geometry, board, blocked.knots, region, state, blocked.box, frame, config,
                  found)
    found.detours += len(out)
    return sorted(out, key=ranking(config))


def _pushes(geometry: ArmGeometry, board: Board, away: np.ndarray, region: np.ndarray,
            state: State, box: str, frame: ApproachFrame, config: Config, found: RoomSearch
            ) -> list[State]:
    """The states after ``box`` is pushed along each direction out of the knots ``away``
    (`clearing_push`), their crowd read on ``region``; tipping pushes counted and left out
    under "refuse"."""
    cfg = config.rearrange
    poses = world_poses(geometry, state.offsets)
    grasp_z = float(frame.positions[-1][2])
    out = []
    for u in directions(frame, cfg.directions, cfg.pull_limit):
        pushed = clearing_push(geometry, board, away, state.offsets, box, u, config)
        if pushed is None:
            continue
        new, travel = pushed
        found.pushes += 1
        moved = moved_boxes(state.offsets, new)
        total = sum(float(np.linalg.norm(new[k] - state.offsets.get(k, np.zeros(2))))
                    for k in moved)
        move = Move(box, (float(u[0]), float(u[1])), float(travel),
                    tuple([box] + [k for k in moved if k != box]))
        move = replace(move, tip_ratio=push_tip_ratio(geometry, poses, move, grasp_z, config))
        tips = move.tip_ratio > 1.0
        if tips and cfg.tipping == "refuse":
            found.tipping += 1
            continue
        out.append(State(new, state.moves + (move,), state.paths, state.travel + total,
                         crowding(geometry, region, new, cfg.deep), state.offsets,
                         state.tips + tips))
    return out


def _signature(offsets: Offsets) -> tuple:
    """A board state's identity, offsets rounded to 5 mm."""
    return tuple(sorted((k, *np.round(v / 0.005).astype(int).tolist())
                        for k, v in offsets.items() if np.linalg.norm(v) > 1e-6))


def search_room(geometry: ArmGeometry, clearance: ShelfClearance, frame: ApproachFrame,
                region: np.ndarray, q0: np.ndarray, rotation: np.ndarray, config: Config,
                deadline: Deadline) -> RoomSearch:
    """The beam search (module docstring) from the boxes at rest; ``q0`` (8,): the reach's
    first knot, where every action starts and ends; ``rotation`` (3, 3): G's at the pre-grasp;
    ``clearance``: the arm against the static shelf."""
    cfg = config.rearrange
    board = Board(geometry.scene, cfg.chain)
    found = RoomSearch()
    beam = [State({}, crowd=crowding(geometry, region, {}, cfg.deep))]
    seen = {_signature({})}
    for depth in range(1, cfg.max_moves + 1):
        found.depth = depth
        candidates: list[tuple[State, State]] = []
        for state in beam:
            if deadline.spend("search"):
                return found
            found.expanded += 1
            candidates += [(child, state) for child in
                           children(geometry, board, region, state, frame, config, found)]
        candidates.sort(key=lambda pair: ranking(config)(pair[0]))
        beam, blocked = _kept(geometry, clearance, frame, q0, rotation, candidates, seen,
                              config, deadline, found)
        if len(found.goals) >= cfg.sequences:
            return found
        if cfg.clear_ways and len(beam) < cfg.beam_width and not deadline.spend("detours"):
            ways = [(child, parent) for parent, b in blocked for child in
                    detours(geometry, board, region, parent, b, frame, config, found)]
            ways.sort(key=lambda pair: ranking(config)(pair[0]))
            more, _ = _kept(geometry, clearance, frame, q0, rotation, ways, seen, config,
                            deadline, found, cfg.beam_width - len(beam))
            beam += more
            if len(found.goals) >= cfg.sequences:
                return found
        if not beam:
            return found
    return found


def _kept(geometry: ArmGeometry, clearance: ShelfClearance, frame: ApproachFrame,
          q0: np.ndarray, rotation: np.ndarray, candidates: list[tuple[State, State]],
          seen: set, config: Config, deadline: Deadline, found: RoomSearch,
          width: int | None = None) -> tuple[list[State], list[tuple[State, Blocked]]]:
    """The first ``width`` (default ``beam_width``) of the ranked (child, parent) pairs not
    seen before whose push has a path (the goals among them go to ``found.goals``), and the
    (parent, blocking box) of each refused push, a box once per parent (with
    ``rearrange.clear_ways`` only)."""
    cfg = config.rearrange
    width = cfg.beam_width if width is None else width
    beam: list[State] = []
    blocked: list[tuple[State, Blocked]] = []
    named: set[tuple[int, str]] = set()
    for child, parent in candidates:
        if len(beam) >= width or deadline.spend("actions"):
            break
        signature = _signature(child.offsets)
        if signature in seen:
            continue
        by: list[Blocked] = []
        path, why = action_path(geometry, clearance, frame, q0, rotation, child.previous,
                                child.offsets, child.moves[-1], config,
                                by if cfg.clear_ways else None)
        if path is None:
            found.refused += 1
            found.reasons.append(f"{child.moves[-1].box}: {why}")
            for b in by:
                if (id(parent), b.box) not in named:
                    named.add((id(parent), b.box))
                    blocked.append((parent, b))
            continue
        seen.add(signature)
        done = replace(child, paths=child.paths + (path,))
        if not done.crowd:
            found.goals.append(done)
            if len(found.goals) >= cfg.sequences:
                break
        else:
            beam.append(done)
    return beam, blocked
