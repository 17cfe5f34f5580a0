"""Engine-neutral scripted contact scenarios and quasi-static mechanics' prediction for them.

Frames and units: W is z up, metres, seconds, kilograms. The board is a 1 m x 1 m slab whose
top face is at ``BOARD_TOP``; its x runs from 0 to 1 (the push goes along +x), y from -0.5 to
0.5. A walled board (squeezes) adds the refrigerator's back wall at x = 1 (and side walls and
a ceiling out of reach). The pusher is a horizontal capsule, its axis along y, that moves along
+x at constant speed and then holds still: the kinematic arm reduced to one link.

Families (`default_scenarios`):

* ``single`` - one box pushed ``distance`` along the board at a fraction of its height; the grid
  of `SingleGrid`. Quasi-static mechanics: a slowly pushed box tips when
  mu_b z > (w / 2)(1 + mu_b mu_p) (z the push height, w the box's length along the push, mu_b
  the box-board pair, mu_p the pusher-box pair), else it slides upright.
* ``chain`` - the pusher drives box A into box B 1 cm ahead of it.
* ``edge`` - a box pushed 6 cm toward the board's far edge from 2-8 cm away; its centre of mass
  stays over the board, so it stays there.
* ``squeeze`` - a box standing against the wall; the pusher advances 1, 2 or 5 mm past contact
  and holds. Hard contact cannot give way: a jam.
* ``topple`` - a thin box pushed high falls over and lands near where it tipped.
* ``drag`` - a box launched along the bare board slides to rest; its deceleration gives the
  realised box-board friction and its rise the engine's lift.

Friction is given per pair of bodies (``Scenario.friction``: "board" is the static shelf, walls
included, "pusher" the capsule); each engine realises the pairs with its own combination rule
(`friction`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path

from drake_clutter.common.typed_yaml import InputError, from_data, read_yaml_file
from drake_clutter.scene.mechanics import tip_ratio
from drake_clutter.scene.scenes import BoxObject, RobotPlacement, Scene, Shelf, Walls

FAMILIES: tuple[str, ...] = ("single", "chain", "edge", "squeeze", "topple", "drag")
BOARD_TOP = 0.75  # m, z of the board's top face in W
BOARD = Shelf(kind="bookshelf", depth=1.0, width=1.0, thickness=0.03, top_height=BOARD_TOP,
              center_xy=(0.5, 0.0))
WALL_THICKNESS = 0.02  # m
WALLED_BOARD = Shelf(kind="fridge", depth=1.0 + WALL_THICKNESS,
                     width=1.0 + 2 * WALL_THICKNESS, thickness=0.03, top_height=BOARD_TOP,
                     center_xy=(0.5 + WALL_THICKNESS / 2, 0.0),
                     walls=Walls(thickness=WALL_THICKNESS, height=0.36))  # wall face at x = 1
APPROACH_GAP = 0.001  # m between the pusher and the box it first meets, at the start
RAMP = 0.5  # s the pusher takes to reach its speed from rest, and to stop
BOARD_CLEARANCE = 0.005  # m the capsule must keep above the board (else the case is left out)
GRAVITY = 9.81  # m/s^2


class GridError(InputError):
    """A grid file is invalid: names the file, the field and the reason."""


@dataclass(frozen=True)
class SingleGrid:
    """The single-push family's grid (the YAML ``single:`` mapping of ``--grid``)."""

    # box lengths along the push, m; ours
    lengths: tuple[float, ...] = (0.03, 0.05, 0.08, 0.12)
    # box widths across the push, m; ours
    widths: tuple[float, ...] = (0.06,)
    # box heights, m; ours
    heights: tuple[float, ...] = (0.10, 0.16, 0.22)
    # heights of the capsule's axis, fractions of the box's height, unitless; ours
    push_heights: tuple[float, ...] = (0.25, 0.5, 0.75)
    # box masses, kg; ours
    masses: tuple[float, ...] = (0.2, 1.0)
    # box-board pair friction coefficients, unitless; ours
    board_friction: tuple[float, ...] = (0.3, 0.6)
    # pusher-box pair friction coefficient, unitless; ours
    pusher_friction: float = 0.5
    # capsule radius, m; ours
    pusher_radius: float = 0.04
    # pusher speed, m/s; ours
    speed: float = 0.08
    # how far the pusher drives the box, m; ours
    distance: float = 0.10
    # time simulated after the pusher stops, s; ours
    hold: float = 1.0


@dataclass(frozen=True)
class GridFile:
    """A ``--grid`` YAML document: the families it sets (only ``single`` today)."""

    single: SingleGrid = field(default_factory=SingleGrid)


@dataclass(frozen=True)
class ScriptedBox:
    """A box resting on the board: full ``size`` along x (the push), y, z; centre ``xy``."""

    name: str
    size: tuple[float, float, float]
    xy: tuple[float, float]
    mass: float
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m/s at the start, W


@dataclass(frozen=True)
class Pusher:
    """The capsule: its axis along y, ``start`` its centre in W, moving ``travel`` along +x and
    holding there. Its speed follows a trapezoid: up from rest to ``speed`` over ``ramp`` s,
    then constant, then down to rest over ``ramp`` s (a slow push without an impact); a travel
    shorter than ``speed`` x ``ramp`` ramps over travel / speed instead (a triangle)."""

    radius: float
    length: float  # m, the cylinder's length along y
    start: tuple[float, float, float]
    travel: float
    speed: float
    ramp: float = 0.0

    @property
    def push_time(self) -> float:
        """s the pusher moves."""
        return self.travel / self.speed + self._ramp

    @property
    def _ramp(self) -> float:
        """s of each ramp: ``ramp``, shortened so that the two fit in the travel."""
        return min(self.ramp, self.travel / self.speed)

    def x_at(self, t: float) -> float:
        """x of the capsule's centre at time t (W, m)."""
        return self.start[0] + self._distance(min(max(t, 0.0), self.push_time))

    def speed_at(self, t: float) -> float:
        """The capsule's speed along +x at time t (m/s)."""
        ramp = self._ramp
        if ramp <= 0:
            return self.speed if 0 <= t < self.push_time else 0.0
        end = self.push_time
        if t < 0 or t >= end:
            return 0.0
        return self.speed * min(1.0, t / ramp, (end - t) / ramp)

    def _distance(self, t: float) -> float:
        v, r, end = self.speed, self._ramp, self.push_time
        if r <= 0:
            return v * t
        if t <= r:
            return v * t * t / (2 * r)
        if t <= end - r:
            return v * (t - r / 2)
        return self.travel - v * (end - t) ** 2 / (2 * r)


@dataclass(frozen=True)
class Scenario:
    """One scripted case: the board, boxes, the pusher (None for drags), pair frictions."""

    family: str
    name: str
    shelf: Shelf
    boxes: tuple[ScriptedBox, ...]
    pusher: Pusher | None
    friction: tuple[tuple[str, str, float], ...]
    hold: float
    prediction: str = ""  # quasi-static mechanics: "slides", "tips", "stays", "lands", ""
    ratio: float | None = None  # single pushes: mu_b z / ((w / 2)(1 + mu_b mu_p))
    parameters: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """s simulated: the push, then the hold."""
        return (self.pusher.push_time if self.pusher else 0.0) + self.hold

    @property
    def bodies(self) -> tuple[str, ...]:
        """Names of the bodies that carry a friction coefficient."""
        return ("board", *(("pusher",) if self.pusher else ()), *(b.name for b in self.boxes))

    def pair(self, a: str, b: str) -> float:
        """The pair friction coefficient of two bodies (KeyError if the pair is not given)."""
        for x, y, mu in self.friction:
            if {x, y} == {a, b}:
                return mu
        raise KeyError((a, b))

    def box_z(self, box: ScriptedBox) -> float:
        """z (W) of a resting box's centre."""
        return self.shelf.top_height + box.size[2] / 2


def scenario_scene(scenario: Scenario, coefficients: dict[str, float]) -> Scene:
    """The scenario's board and boxes as a `Scene` (for the world builders), each box carrying
    ``coefficients[name]`` as its friction (an engine's realisation of the pairs)."""
    boxes = tuple(BoxObject(b.name, b.size, (b.xy[0], b.xy[1], 0.0),
                            b.mass / (b.size[0] * b.size[1] * b.size[2]), coefficients[b.name])
                  for b in scenario.boxes)
    return Scene(scenario.name, scenario.shelf, RobotPlacement(), boxes[0].name, boxes)


def _pusher_behind(box: ScriptedBox, push_z: float, radius: float, length: float,
                   travel: float, speed: float) -> Pusher:
    x = box.xy[0] - box.size[0] / 2 - radius - APPROACH_GAP
    return Pusher(radius, length, (x, box.xy[1], BOARD_TOP + push_z), travel, speed, RAMP)


def _pairs(boxes: tuple[ScriptedBox, ...], board: float | tuple[float, ...], pusher: float | None,
           between: float | None = None) -> tuple[tuple[str, str, float], ...]:
    boards = board if isinstance(board, tuple) else (board,) * len(boxes)
    pairs = [("board", b.name, mu) for b, mu in zip(boxes, boards, strict=True)]
    if pusher is not None:
        pairs += [("pusher", b.name, pusher) for b in boxes]
    if between is not None:
        pairs += [(a.name, b.name, between) for a, b in itertools.combinations(boxes, 2)]
    return tuple(pairs)


def single_scenarios(grid: SingleGrid = SingleGrid()) -> list[Scenario]:
    """The single-push family over ``grid`` (cases whose capsule would touch the board left
    out), with quasi-static mechanics' prediction."""
    out = []
    r = grid.pusher_radius
    for w, width, h, frac, m, mu_b in itertools.product(
            grid.lengths, grid.widths, grid.heights, grid.push_heights, grid.masses,
            grid.board_friction):
        z = frac * h
        if z - r < BOARD_CLEARANCE:
            continue
        box = ScriptedBox("box", (w, width, h), (0.5, 0.0), m)
        ratio = tip_ratio(w, z, mu_b, grid.pusher_friction)
        out.append(Scenario(
            "single", f"single_w{w:g}_h{h:g}_z{frac:g}_m{m:g}_mu{mu_b:g}_d{width:g}",
            BOARD, (box,), _pusher_behind(box, z, r, 2 * width, APPROACH_GAP + grid.distance,
                                          grid.speed),
            _pairs((box,), mu_b, grid.pusher_friction), grid.hold,
            "tips" if ratio > 1 else "slides", ratio,
            {"length": w, "width": width, "height": h, "push_height": frac, "mass": m,
             "board_friction": mu_b}))
    return out


def chain_scenarios(grid: SingleGrid = SingleGrid()) -> list[Scenario]:
    """The pusher drives box A (10 cm tall, pushed low) 10 cm into box B, 1 cm ahead of it:
    A's length x B's length x B's height x the box-board pair (16 cases)."""
    out = []
    r, z = grid.pusher_radius, grid.pusher_radius + 0.01
    for la, lb, hb, mu_b in itertools.product((0.06, 0.10), (0.04, 0.08), (0.10, 0.20),
                                              (0.3, 0.6)):
        a = ScriptedBox("box_a", (la, 0.06, 0.10), (0.4, 0.0), 0.4)
        b = ScriptedBox("box_b", (lb, 0.06, hb), (0.4 + la / 2 + 0.01 + lb / 2, 0.0), 0.3)
        out.append(Scenario(
            "chain", f"chain_la{la:g}_lb{lb:g}_hb{hb:g}_mu{mu_b:g}", BOARD, (a, b),
            _pusher_behind(a, z, r, 0.12, APPROACH_GAP + grid.distance, grid.speed),
            _pairs((a, b), mu_b, grid.pusher_friction, between=0.5), grid.hold, "",
            None, {"length_a": la, "length_b": lb, "height_b": hb, "board_friction": mu_b}))
    return out


def edge_scenarios(grid: SingleGrid = SingleGrid()) -> list[Scenario]:
    """A box pushed 6 cm toward the board's far edge (x = 1) from 2-8 cm away, low enough to
    slide: its centre ends at least 1 cm inside the edge, so mechanics keeps it on the board
    (12 cases)."""
    out = []
    r, z = grid.pusher_radius, grid.pusher_radius + 0.01
    for gap, length in itertools.product((0.02, 0.04, 0.06, 0.08), (0.10, 0.12, 0.14)):
        box = ScriptedBox("box", (length, 0.06, 0.10), (1.0 - gap - length / 2, 0.0), 0.3)
        out.append(Scenario(
            "edge", f"edge_gap{gap:g}_w{length:g}", BOARD, (box,),
            _pusher_behind(box, z, r, 0.12, APPROACH_GAP + 0.06, grid.speed),
            _pairs((box,), 0.3, grid.pusher_friction), grid.hold, "stays", None,
            {"gap": gap, "length": length}))
    return out


SQUEEZES = (0.001, 0.002, 0.005)  # m the pusher advances past contact


def squeeze_scenarios(grid: SingleGrid = SingleGrid()) -> list[Scenario]:
    """A 6 x 6 x 12 cm box standing against the back wall; the capsule advances 1, 2 or 5 mm
    past contact (pushed low) and holds 0.5 s."""
    out = []
    r, z = grid.pusher_radius, grid.pusher_radius + 0.01
    for depth in SQUEEZES:
        box = ScriptedBox("box", (0.06, 0.06, 0.12), (1.0 - 0.03, 0.0), 0.3)
        out.append(Scenario(
            "squeeze", f"squeeze_{depth * 1000:g}mm", WALLED_BOARD, (box,),
            _pusher_behind(box, z, r, 0.12, APPROACH_GAP + depth, grid.speed),
            _pairs((box,), 0.3, grid.pusher_friction), 0.5, "jam", None, {"depth": depth}))
    return out


def topple_scenarios(grid: SingleGrid = SingleGrid()) -> list[Scenario]:
    """A 3.5 x 3.5 x 22 cm box (fig5's small_tippy) pushed at 3/4 of its height falls over and
    lands near where it tipped, on the board."""
    box = ScriptedBox("box", (0.035, 0.035, 0.22), (0.5, 0.0), 0.1)
    z = 0.75 * box.size[2]
    ratio = tip_ratio(box.size[0], z, 0.6, grid.pusher_friction)
    return [Scenario("topple", "topple_thin", BOARD, (box,),
                     _pusher_behind(box, z, grid.pusher_radius, 0.12, APPROACH_GAP + grid.distance,
                                    grid.speed),
                     _pairs((box,), 0.6, grid.pusher_friction), 1.5, "lands", ratio, {})]


def drag_scenarios() -> list[Scenario]:
    """A 6 cm cube of 0.3 kg launched along +x on the bare board: 1 m/s on pairs 0.3, 0.5 and
    0.6 (the realised coefficient), 2 m/s on 0.3 and 0.6 (the lift of a fast slide)."""
    out = []
    for v0, mu in ((1.0, 0.3), (1.0, 0.5), (1.0, 0.6), (2.0, 0.3), (2.0, 0.6)):
        box = ScriptedBox("box", (0.06, 0.06, 0.06), (0.1, 0.0), 0.3, (v0, 0.0, 0.0))
        out.append(Scenario("drag", f"drag_v{v0:g}_mu{mu:g}", BOARD, (box,), None,
                            _pairs((box,), mu, None), 1.0, "slides", None,
                            {"speed": v0, "board_friction": mu}))
    return out


def default_scenarios(grid: SingleGrid = SingleGrid(),
                      families: tuple[str, ...] = FAMILIES) -> list[Scenario]:
    """Every case of the named families (single pushes over ``grid``; the others use its
    pusher's radius, friction and speed)."""
    makers = {"single": single_scenarios, "chain": chain_scenarios, "edge": edge_scenarios,
              "squeeze": squeeze_scenarios, "topple": topple_scenarios,
              "drag": lambda _grid: drag_scenarios()}
    return [s for family in families for s in makers[family](grid)]


def _check_grid(grid: SingleGrid, file: str) -> None:
    for name in ("lengths", "widths", "heights", "push_heights", "masses", "board_friction"):
        values = getattr(grid, name)
        if not values:
            raise GridError(file, f"single.{name}", "must list at least one value")
        for i, v in enumerate(values):
            if not v > 0:
                raise GridError(file, f"single.{name}[{i}]", f"must be positive, got {v!r}")
    for i, v in enumerate(grid.push_heights):
        if v >= 1:
            raise GridError(file, f"single.push_heights[{i}]",
                            f"must be a fraction of the height below 1, got {v!r}")
    for name in ("pusher_friction", "pusher_radius", "speed", "distance"):
        value = getattr(grid, name)
        if not value > 0:
            raise GridError(file, f"single.{name}", f"must be positive, got {value!r}")
    if grid.hold < 0:
        raise GridError(file, "single.hold", f"must be >= 0, got {grid.hold!r}")
    if not single_scenarios(grid):
        raise GridError(file, "single", "every case puts the capsule on the board "
                        "(push_heights x heights must clear pusher_radius)")


def load_grid(path: str | Path) -> SingleGrid:
    """The single-push grid of a ``--grid`` YAML file (every field required; see docs/phi.md).

    Raises GridError naming the file, the field and the reason."""
    data = read_yaml_file(path, error_cls=GridError)
    if not isinstance(data, dict):
        raise GridError(path, "", "a grid must be a YAML mapping of families")
    unknown = sorted(set(data) - {"single"})
    if unknown:
        raise GridError(path, unknown[0], "unknown family (a grid file sets: single)")
    if "single" not in data:
        raise GridError(path, "single", "missing (a grid file sets the single-push family)")
    single = data["single"]
    if not isinstance(single, dict):
        raise GridError(path, "single", "must be a mapping of the grid's fields")
    missing = [name for name in SingleGrid.__dataclass_fields__ if name not in single
               and name != "hold"]
    if missing:
        raise GridError(path, f"single.{missing[0]}", "missing")
    grid = from_data(GridFile, data, file=path, error_cls=GridError).single
    _check_grid(grid, str(path))
    return grid
