"""Random scene generation (Sec. VI-B) and the named scene sets.

A bookshelf or refrigerator scene with N boxes (the target included): every box's size,
planar position, yaw, density and friction are drawn uniformly from the ranges in
`GeneratorConfig` (documented there), by random sequential placement without overlap. The
target is placed first, in the region the PR2's right arm reaches (``target_depth`` behind
the board's front edge, within ``target_lateral`` of the shoulder's y). A box that finds no
free spot in ``max_tries_per_box`` draws is re-drawn (new size and yaw); the densest levels
therefore end with the board nearly full of boxes that fit.

All randomness comes from ``numpy.random.default_rng(seed)``; values are rounded (0.1 mm,
0.1 mrad, 1 kg/m^3, 0.01 friction) so files are short, and the same seed gives a
byte-identical file.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from drake_clutter.common.config import BoxRanges, GeneratorConfig
from drake_clutter.robot import pr2
from drake_clutter.scene.scenes import (
    BoxObject,
    Provenance,
    RobotPlacement,
    Scene,
    Shelf,
    ShelfKind,
    footprints_overlap,
    validate_scene,
)
from drake_clutter.scene.shelf import environment, make_shelf

TARGET_NAME = "target"
TARGET_COLOR = (0.1, 0.8, 0.2, 1.0)  # green, as in the paper's figures
OBSTACLE_COLOR = (0.75, 0.2, 0.75, 1.0)  # magenta, as in Fig. 1


class GenerationError(RuntimeError):
    """The generator could not place the requested boxes with these settings."""


@dataclass(frozen=True)
class SceneSpec:
    """One scene to generate: environment kind, number of boxes (target included) and seed."""

    kind: ShelfKind
    num_objects: int
    seed: int

    @property
    def name(self) -> str:
        """Stable scene name, e.g. ``bookshelf_n25_s2015``."""
        return f"{self.kind}_n{self.num_objects:02d}_s{self.seed}"

    @staticmethod
    def from_name(name: str) -> SceneSpec | None:
        """The spec a generated scene's `name` stands for; None for any other name."""
        match = _SCENE_NAME.fullmatch(name)
        if match is None:
            return None
        return SceneSpec(match["kind"], int(match["n"]), int(match["seed"]))


_SCENE_NAME = re.compile(r"(?P<kind>bookshelf|fridge)_n(?P<n>\d+)_s(?P<seed>\d+)")


def make_robot_placement(config: GeneratorConfig) -> RobotPlacement:
    """Robot base at the origin facing +x, shifted so the right shoulder faces the board centre;
    torso lifted so the shoulder is ``shoulder_above_board`` above the board (clamped to limits)."""
    lo, hi = pr2.TORSO_LIMITS
    torso = config.board_top_height + config.shoulder_above_board
    torso -= pr2.SHOULDER_PAN_HEIGHT_AT_ZERO_TORSO
    torso = round(min(hi, max(lo, torso)), 4)
    # Shift the base sideways so that the right shoulder-pan axis lies at y = 0 (board centre).
    shoulder_y = shoulder_xy(RobotPlacement((0.0, 0.0, 0.0), torso))[1]
    return RobotPlacement(base_pose=(0.0, round(-float(shoulder_y), 6), 0.0), torso_height=torso)


def shoulder_xy(robot: RobotPlacement) -> np.ndarray:
    """(x, y) in W of the right shoulder-pan axis for a robot placement."""
    pan = next(j for j in pr2.JOINTS if j.name == pr2.ARM_JOINTS[0])
    p_base = pr2.X_BaseTorso(robot.torso_height)[:3, 3] + np.asarray(pan.xyz)
    x, y, yaw = robot.base_pose
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([x + c * p_base[0] - s * p_base[1], y + s * p_base[0] + c * p_base[1]])


def _uniform(rng: np.random.Generator, r) -> float:
    return float(rng.uniform(r.low, r.high))


def _draw_box(rng: np.random.Generator, ranges: BoxRanges, name: str, color,
              max_height: float) -> BoxObject:
    """A box with size, yaw, density and friction drawn; its position is set when placed."""
    size = (round(_uniform(rng, ranges.footprint), 4), round(_uniform(rng, ranges.footprint), 4),
            round(min(_uniform(rng, ranges.height), max_height), 4))
    return BoxObject(name=name, size=size, pose=(0.0, 0.0, round(_uniform(rng, ranges.yaw), 4)),
                     density=float(round(_uniform(rng, ranges.density))),
                     friction=round(_uniform(rng, ranges.friction), 2), color=color)


class _FreeSpace:
    """The board rasterised at ``CELL`` m, to sample box centres uniformly where a box fits.

    For a new box, the cells where its centre may go are the board's cells minus the
    dilation of the occupied cells by the box's own (inflated) footprint; a sampled centre is
    then checked exactly (separating axes, with the minimum gap) before it is accepted.
    """

    CELL = 0.004

    def __init__(self, bounds, gap: float):
        self.x0, x1, self.y0, y1 = bounds
        self.bounds, self.gap = bounds, gap
        self.shape = (int((x1 - self.x0) / self.CELL), int((y1 - self.y0) / self.CELL))
        ix, iy = np.indices(self.shape)
        self.centres = np.stack([self.x0 + (ix + 0.5) * self.CELL,
                                 self.y0 + (iy + 0.5) * self.CELL], axis=-1)
        self.occupied = np.zeros(self.shape, dtype=bool)
        self.placed: list[np.ndarray] = []

    def _inside(self, corners: np.ndarray, points: np.ndarray, inflate: float) -> np.ndarray:
        """Mask of ``points`` inside the footprint ``corners`` grown by ``inflate``."""
        inside = np.ones(points.shape[:-1], dtype=bool)
        for k in range(4):
            edge = corners[(k + 1) % 4] - corners[k]
            normal = np.array([edge[1], -edge[0]]) / np.linalg.norm(edge)  # outward (CCW)
            inside &= (points - corners[k]) @ normal <= inflate
        return inside

    def candidates(self, box: BoxObject, region) -> np.ndarray:
        """Cell centres in ``region`` where ``box`` (at its yaw) fits, as an (N, 2) array."""
        probe = replace(box, pose=(0.0, 0.0, box.pose[2])).footprint()
        half = np.abs(probe).max(axis=0) + self.gap
        r = int(np.ceil(half.max() / self.CELL)) + 1
        offsets = (np.stack(np.indices((2 * r + 1, 2 * r + 1)), axis=-1) - r) * self.CELL
        kernel = self._inside(probe, offsets, self.gap + self.CELL)
        blocked = ndimage.binary_dilation(self.occupied, structure=kernel) if self.placed \
            else np.zeros(self.shape, dtype=bool)
        x, y = self.centres[..., 0], self.centres[..., 1]
        (rx0, rx1), (ry0, ry1) = region
        ok = ~blocked & (x >= max(rx0, self.x0 + half[0]))
        ok &= x <= min(rx1, self.bounds[1] - half[0])
        ok &= (y >= max(ry0, self.y0 + half[1])) & (y <= min(ry1, self.bounds[3] - half[1]))
        return self.centres[ok]

    def fits(self, box: BoxObject) -> bool:
        """Exact check: inside the bounds and at least ``gap`` from every placed box."""
        corners = box.footprint()
        x0, x1, y0, y1 = self.bounds
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        if lo[0] < x0 + self.gap or hi[0] > x1 - self.gap:
            return False
        if lo[1] < y0 + self.gap or hi[1] > y1 - self.gap:
            return False
        return not any(footprints_overlap(corners, p, tol=-self.gap) for p in self.placed)

    def add(self, box: BoxObject) -> None:
        """Marks a placed box's footprint as occupied."""
        corners = box.footprint()
        self.placed.append(corners)
        self.occupied |= self._inside(corners, self.centres, 0.0)


def _place(rng, box: BoxObject, space: _FreeSpace, region, config) -> BoxObject | None:
    """``box`` moved to a uniformly drawn free centre in ``region``; None if it fits nowhere."""
    cells = space.candidates(box, region)
    for _ in range(min(len(cells), config.max_tries_per_box)):
        cx, cy = cells[rng.integers(len(cells))] + rng.uniform(-0.5, 0.5, 2) * space.CELL
        moved = replace(box, pose=(round(float(cx), 4), round(float(cy), 4), box.pose[2]))
        if space.fits(moved):
            return moved
    return None


def _max_box_height(shelf: Shelf, config: GeneratorConfig) -> float:
    """Tallest box that fits under a fridge's ceiling with the minimum gap (inf on a bookshelf)."""
    return shelf.walls.height - config.min_gap if shelf.walls else math.inf


def _place_or_redraw(rng, ranges, name, color, shelf: Shelf, space, region, config):
    max_height = _max_box_height(shelf, config)
    box = _draw_box(rng, ranges, name, color, max_height)
    for _ in range(config.max_redraws_per_box):
        placed = _place(rng, box, space, region, config)
        if placed is not None:
            space.add(placed)
            return placed
        box = _draw_box(rng, ranges, name, color, max_height)
    raise GenerationError(f"could not place box '{name}' without overlap after "
                          f"{config.max_redraws_per_box} size draws")


def _populate(rng, shelf: Shelf, target_region, num_objects: int,
              config: GeneratorConfig) -> list[BoxObject]:
    """One attempt at placing the target and ``num_objects - 1`` obstacles on the board."""
    x0, x1, y0, y1 = shelf.interior_bounds()
    space = _FreeSpace((x0, x1, y0, y1), config.min_gap)
    boxes = [_place_or_redraw(rng, config.target, TARGET_NAME, TARGET_COLOR, shelf, space,
                              target_region, config)]
    max_height = _max_box_height(shelf, config)
    drawn = [_draw_box(rng, config.boxes, "", OBSTACLE_COLOR, max_height)
             for _ in range(num_objects - 1)]
    drawn.sort(key=lambda b: -b.size[0] * b.size[1])
    for i, box in enumerate(drawn, start=1):
        name = f"box_{i:02d}"
        placed = _place(rng, replace(box, name=name), space, ((x0, x1), (y0, y1)), config)
        if placed is None:
            placed = _place_or_redraw(rng, config.boxes, name, OBSTACLE_COLOR, shelf, space,
                                      ((x0, x1), (y0, y1)), config)
        else:
            space.add(placed)
        boxes.append(placed)
    return boxes


def generate_scene(kind: ShelfKind, num_objects: int, seed: int,
                   config: GeneratorConfig | None = None) -> Scene:
    """A random scene with ``num_objects`` boxes (target included) on a ``kind`` shelf.

    The target is placed first in its reach region; the other boxes are drawn, sorted by
    footprint area (largest first, so small boxes fill the gaps of a dense board) and each
    placed at a centre drawn uniformly from where it fits. Deterministic in ``seed``. Raises
    ValueError for a bad count or a negative seed, GenerationError if the boxes cannot be placed.
    """
    config = config or GeneratorConfig()
    if kind not in ("bookshelf", "fridge"):
        raise ValueError(f"unknown shelf kind {kind!r} (bookshelf or fridge)")
    if num_objects < 1:
        raise ValueError(f"a scene needs at least 1 object (the target), got {num_objects}")
    if seed < 0:
        raise ValueError(f"the seed must be non-negative, got {seed}")
    rng = np.random.default_rng(seed)
    shelf = make_shelf(config, kind)
    robot = make_robot_placement(config)
    x0, x1, y0, y1 = shelf.interior_bounds()
    shoulder_y = shoulder_xy(robot)[1]
    target_region = ((shelf.front_x + config.target_depth.low,
                      min(x1, shelf.front_x + config.target_depth.high)),
                     (max(y0, shoulder_y - config.target_lateral),
                      min(y1, shoulder_y + config.target_lateral)))
    for attempt in range(1, config.max_attempts + 1):
        try:
            boxes = _populate(rng, shelf, target_region, num_objects, config)
            break
        except GenerationError:
            if attempt == config.max_attempts:
                raise
    spec = SceneSpec(kind, num_objects, seed)
    coverage = _coverage(boxes, shelf)
    scene = Scene(
        name=spec.name, shelf=shelf, robot=robot, target=TARGET_NAME, boxes=tuple(boxes),
        description=f"Random {kind} scene with {num_objects} boxes (seed {seed}), "
                    f"covering {coverage:.0%} of the board.",
        provenance=Provenance(generator=kind, seed=seed, parameters={
            "num_objects": num_objects, "board_coverage": round(coverage, 4)}))
    return validate_scene(scene, spec.name)


def _coverage(boxes, shelf: Shelf) -> float:
    x0, x1, y0, y1 = shelf.interior_bounds()
    return sum(b.size[0] * b.size[1] for b in boxes) / ((x1 - x0) * (y1 - y0))


def board_coverage(scene: Scene) -> float:
    """Fraction of the usable board area covered by box footprints."""
    return _coverage(scene.boxes, scene.shelf)


def free_spots(scene: Scene, side: float, gap: float | None = None) -> int:
    """Number of board cells where one more ``side`` x ``side`` box (yaw 0) would still fit."""
    gap = GeneratorConfig().min_gap if gap is None else gap
    space = _FreeSpace(scene.shelf.interior_bounds(), gap)
    for box in scene.boxes:
        space.add(box)
    probe = BoxObject("probe", (side, side, 0.1), (0.0, 0.0, 0.0), 1.0, 0.5)
    x0, x1, y0, y1 = scene.shelf.interior_bounds()
    return len(space.candidates(probe, ((x0, x1), (y0, y1))))


SCENE_SETS = ("paper", "smoke")


def scene_set(name: str, config: GeneratorConfig | None = None) -> list[SceneSpec]:
    """Specs of a named scene set.

    ``paper``: ``scenes_per_level`` scenes per clutter level of both environments (Sec. VI-B:
    10 x (6 + 9) = 150), seeds ``paper_seed_base + 1000 * level_index + i`` (bookshelf levels
    first). ``smoke``: one scene at the lowest and one at a middle level of each environment.
    """
    config = config or GeneratorConfig()
    specs: list[SceneSpec] = []
    if name == "paper":
        levels = [("bookshelf", n) for n in config.bookshelf.clutter_levels]
        levels += [("fridge", n) for n in config.fridge.clutter_levels]
        for li, (kind, n) in enumerate(levels):
            for i in range(config.scenes_per_level):
                specs.append(SceneSpec(kind, n, config.paper_seed_base + 1000 * li + i))
        return specs
    if name == "smoke":
        for kind in ("bookshelf", "fridge"):
            levels = environment(config, kind).clutter_levels
            for n in (levels[0], levels[len(levels) // 2]):
                specs.append(SceneSpec(kind, n, config.paper_seed_base))
        return specs
    raise ValueError(f"unknown scene set {name!r} (known: {', '.join(SCENE_SETS)})")
