"""Scenes: a shelf, boxes on its board, the target, and where the robot stands (Sec. III).

Frames and units. W is the world frame: z up, the floor at z = 0, metres and radians. The
shelf's board is axis-aligned in W with its open front facing -x (towards the robot); its top
surface is at ``shelf.top_height``. Every box rests on the board (Sec. III: "all dynamic
objects are boxes that rest on a single flat, horizontal surface"), so a box pose is planar:
``pose = (x, y, yaw)`` of the box centre in W, yaw about +z; the box's z follows from the board.
Box ``size`` is the full extent along the box's own x, y, z axes.

A `Scene` is immutable and fully validated on load: anything wrong raises `SceneError`
naming the file, the field and the reason. ``save_scene`` writes YAML that ``load_scene`` reads
back to an equal scene, and saving that scene again gives byte-identical text.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Literal

import numpy as np

from drake_clutter.common.typed_yaml import (
    InputError,
    dump_yaml,
    from_data,
    parse_yaml_text,
    read_yaml_file,
    to_data,
)
from drake_clutter.robot import pr2

ShelfKind = Literal["bookshelf", "fridge"]
OVERLAP_TOLERANCE = 1e-6  # m; boxes may touch, not interpenetrate by more than this


class SceneError(InputError):
    """A scene file or scene value is invalid; the message names file, field and reason."""


@dataclass(frozen=True)
class Walls:
    """Refrigerator walls: back wall, two side walls and a ceiling around the board.

    The walls stand on the board's back and side edges (inside its footprint): the usable
    interior is ``depth - thickness`` by ``width - 2 * thickness``. ``height`` is the clear
    interior height from the board's top to the underside of the ceiling.
    """

    thickness: float
    height: float


@dataclass(frozen=True)
class Shelf:
    """The static structure: a horizontal board, with walls for a refrigerator shelf.

    ``center_xy`` is the board centre in W; ``depth`` is its extent along x (away from the
    robot), ``width`` along y, ``thickness`` along z, ``top_height`` the z of its top face.
    """

    kind: ShelfKind
    depth: float
    width: float
    thickness: float
    top_height: float
    center_xy: tuple[float, float]
    walls: Walls | None = None

    @property
    def front_x(self) -> float:
        """x of the board's open front edge in W."""
        return self.center_xy[0] - self.depth / 2

    def interior_bounds(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) in W of the area where boxes may stand."""
        cx, cy = self.center_xy
        x0, x1 = cx - self.depth / 2, cx + self.depth / 2
        y0, y1 = cy - self.width / 2, cy + self.width / 2
        if self.walls is not None:
            t = self.walls.thickness
            x1, y0, y1 = x1 - t, y0 + t, y1 - t
        return x0, x1, y0, y1


@dataclass(frozen=True)
class BoxObject:
    """A movable box resting on the board (pose planar in W, see the module docstring)."""

    name: str
    size: tuple[float, float, float]
    pose: tuple[float, float, float]
    density: float
    friction: float
    color: tuple[float, float, float, float] = (0.8, 0.2, 0.8, 1.0)

    @property
    def volume(self) -> float:
        """m^3."""
        return self.size[0] * self.size[1] * self.size[2]

    @property
    def mass(self) -> float:
        """kg = density x volume."""
        return self.density * self.volume

    def footprint(self) -> np.ndarray:
        """4x2 array of the footprint's corners (x, y) in W, counter-clockwise."""
        x, y, yaw = self.pose
        hx, hy = self.size[0] / 2, self.size[1] / 2
        c, s = math.cos(yaw), math.sin(yaw)
        local = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
        return local @ np.array([[c, s], [-s, c]]) + np.array([x, y])


@dataclass(frozen=True)
class RobotPlacement:
    """Where the PR2 stands: ``base_pose`` = (x, y, yaw) of base_footprint in W, torso lift (m)."""

    base_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torso_height: float = 0.2


@dataclass(frozen=True)
class Provenance:
    """How the scene was made: a generator name ('hand' for hand-made), its seed and parameters."""

    generator: str = "hand"
    seed: int | None = None
    parameters: dict[str, int | float | str] = field(default_factory=dict)


@dataclass(frozen=True)
class Scene:
    """A complete, validated planning problem: shelf, boxes, target, robot placement."""

    name: str
    shelf: Shelf
    robot: RobotPlacement
    target: str
    boxes: tuple[BoxObject, ...]
    description: str = ""
    provenance: Provenance = field(default_factory=Provenance)

    def box(self, name: str) -> BoxObject:
        """The box called ``name`` (KeyError if absent)."""
        for b in self.boxes:
            if b.name == name:
                return b
        raise KeyError(name)

    @property
    def target_box(self) -> BoxObject:
        """The box to grasp."""
        return self.box(self.target)

    def box_center_z(self, box: BoxObject) -> float:
        """z (W) of a resting box's centre."""
        return self.shelf.top_height + box.size[2] / 2


# ----------------------------------------------------------------------------- validation


def _positive(values, file, field_name, what="size"):
    for i, v in enumerate(values):
        if not v > 0:
            raise SceneError(file, f"{field_name}[{i}]" if len(values) > 1 else field_name,
                             f"{what} must be positive, got {v}")


def _validate_shelf(shelf: Shelf, file) -> None:
    _positive((shelf.depth,), file, "shelf.depth", "depth")
    _positive((shelf.width,), file, "shelf.width", "width")
    _positive((shelf.thickness,), file, "shelf.thickness", "thickness")
    if shelf.top_height <= shelf.thickness:
        raise SceneError(file, "shelf.top_height", "the board must stand above the floor "
                         f"(top_height {shelf.top_height} <= thickness {shelf.thickness})")
    if shelf.kind == "bookshelf" and shelf.walls is not None:
        raise SceneError(file, "shelf.walls", "a bookshelf has no walls (use kind: fridge)")
    if shelf.kind == "fridge":
        if shelf.walls is None:
            raise SceneError(file, "shelf.walls", "a fridge shelf needs walls")
        _positive((shelf.walls.thickness,), file, "shelf.walls.thickness", "thickness")
        _positive((shelf.walls.height,), file, "shelf.walls.height", "height")
        if 2 * shelf.walls.thickness >= shelf.width or shelf.walls.thickness >= shelf.depth:
            raise SceneError(file, "shelf.walls.thickness", "walls leave no interior")


def _validate_robot(robot: RobotPlacement, file) -> None:
    lo, hi = pr2.TORSO_LIMITS
    if not lo <= robot.torso_height <= hi:
        raise SceneError(file, "robot.torso_height",
                         f"must lie in [{lo}, {hi}] m, got {robot.torso_height}")


def _validate_box_values(i: int, box: BoxObject, file) -> None:
    where = f"boxes[{i}]"
    if not box.name.strip():
        raise SceneError(file, f"{where}.name", "must not be empty")
    _positive(box.size, file, f"{where}.size")
    _positive((box.density,), file, f"{where}.density", "density")
    if box.friction < 0:
        raise SceneError(file, f"{where}.friction", f"must be >= 0, got {box.friction}")
    for j, c in enumerate(box.color):
        if not 0 <= c <= 1:
            raise SceneError(file, f"{where}.color[{j}]", f"must lie in [0, 1], got {c}")


def _validate_box_on_shelf(i: int, box: BoxObject, shelf: Shelf, file) -> None:
    where = f"boxes[{i}].pose"
    corners = box.footprint()
    x0, x1, y0, y1 = shelf.interior_bounds()
    bx0, by0 = corners.min(axis=0)
    bx1, by1 = corners.max(axis=0)
    tol = OVERLAP_TOLERANCE
    walled = shelf.walls is not None
    excess = {
        "front edge of the board": x0 - bx0,
        "back wall" if walled else "back edge of the board": bx1 - x1,
        "right wall" if walled else "right edge of the board": y0 - by0,
        "left wall" if walled else "left edge of the board": by1 - y1,
    }
    for side, depth in excess.items():
        if depth > tol:
            kind = "inside a wall" if "wall" in side else "off the board"
            raise SceneError(file, where, f"box '{box.name}' crosses the {side} by "
                             f"{depth:.4f} m ({kind})")
    if walled and box.size[2] > shelf.walls.height + tol:
        raise SceneError(file, f"boxes[{i}].size[2]", f"box '{box.name}' is {box.size[2]} m "
                         f"tall, taller than the fridge interior ({shelf.walls.height} m)")


def footprints_overlap(a: np.ndarray, b: np.ndarray, tol: float = OVERLAP_TOLERANCE) -> bool:
    """True when two convex footprints (Nx2 corner arrays, W) interpenetrate by more than tol.

    Separating-axis test over both polygons' edge normals.
    """
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        pa, pb = a @ normals.T, b @ normals.T
        overlap = np.minimum(pa.max(0), pb.max(0)) - np.maximum(pa.min(0), pb.min(0))
        if np.any(overlap <= tol):
            return False
    return True


def fits_on_shelf(box: BoxObject, shelf: Shelf) -> bool:
    """True when the box's footprint lies on the board and inside any walls (to within
    OVERLAP_TOLERANCE), as `validate_scene` requires of every box."""
    try:
        _validate_box_on_shelf(0, box, shelf, "<box>")
    except SceneError:
        return False
    return True


def validate_scene(scene: Scene, file: str | Path = "<scene>") -> Scene:
    """Checks the scene's meaning (types are checked on load); returns it or raises SceneError."""
    if not scene.name.strip():
        raise SceneError(file, "name", "must not be empty")
    _validate_shelf(scene.shelf, file)
    _validate_robot(scene.robot, file)
    if not scene.boxes:
        raise SceneError(file, "boxes", "a scene needs at least the target box")
    seen: dict[str, int] = {}
    for i, box in enumerate(scene.boxes):
        _validate_box_values(i, box, file)
        if box.name in seen:
            raise SceneError(file, f"boxes[{i}].name",
                             f"duplicate box name '{box.name}' (also boxes[{seen[box.name]}])")
        seen[box.name] = i
        _validate_box_on_shelf(i, box, scene.shelf, file)
    if scene.target not in seen:
        raise SceneError(file, "target", f"'{scene.target}' names no box; the boxes are: "
                         + ", ".join(sorted(seen)[:10]) + (" ..." if len(seen) > 10 else ""))
    corners = [b.footprint() for b in scene.boxes]
    for i in range(len(corners)):
        for j in range(i + 1, len(corners)):
            if footprints_overlap(corners[i], corners[j]):
                raise SceneError(file, f"boxes[{j}].pose", f"boxes '{scene.boxes[i].name}' and "
                                 f"'{scene.boxes[j].name}' overlap")
    return scene


# ----------------------------------------------------------------------------- YAML I/O


def scene_from_data(data, file: str | Path = "<scene>") -> Scene:
    """Builds and validates a Scene from parsed YAML data; raises SceneError."""
    if not isinstance(data, dict):
        raise SceneError(file, "", f"a scene must be a YAML mapping, got {type(data).__name__}")
    scene = from_data(Scene, data, file=file, error_cls=SceneError)
    return validate_scene(scene, file)


def scene_from_text(text: str, file: str | Path = "<scene>") -> Scene:
    """Parses and validates scene YAML text; raises SceneError."""
    return scene_from_data(parse_yaml_text(text, file=file, error_cls=SceneError), file)


def load_scene(path: str | Path) -> Scene:
    """Reads and validates a scene YAML file; raises SceneError naming the file."""
    return scene_from_data(read_yaml_file(path, error_cls=SceneError), path)


def scene_to_text(scene: Scene) -> str:
    """Deterministic YAML for a scene (the description also heads the file as a comment)."""
    header = "".join(f"# {line}\n" for line in scene.description.splitlines())
    return header + dump_yaml(to_data(scene))


def save_scene(scene: Scene, path: str | Path) -> Path:
    """Validates and writes the scene as YAML; returns the path."""
    validate_scene(scene, path)
    path = Path(path)
    try:
        path.write_text(scene_to_text(scene), encoding="utf-8")
    except OSError as exc:
        raise SceneError(path, "", f"cannot write the scene file: {exc.strerror}") from None
    return path


# ----------------------------------------------------------------------------- shipped scenes

SHIPPED_PACKAGE = "drake_clutter.scene.shipped"
DEFAULT_SCENE = "default_push"


def shipped_scene_names() -> list[str]:
    """Names of the scenes shipped with the package (YAML files in scene/shipped/)."""
    files = resources.files(SHIPPED_PACKAGE).iterdir()
    return sorted(f.name[:-5] for f in files if f.name.endswith(".yaml"))


def load_shipped_scene(name: str) -> Scene:
    """Loads a shipped scene by name; SceneError listing the names if unknown."""
    names = shipped_scene_names()
    if name not in names:
        raise SceneError(name, "", "no such scene file and no shipped scene of that name "
                         f"(shipped: {', '.join(names)})")
    ref = resources.files(SHIPPED_PACKAGE) / f"{name}.yaml"
    return scene_from_text(ref.read_text(encoding="utf-8"), file=f"<shipped>/{name}.yaml")


def resolve_scene(spec: str) -> Scene:
    """A scene from a path to a YAML file or the name of a shipped scene."""
    path = Path(spec)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return load_scene(path)
    return load_shipped_scene(spec)
