"""Meshcat replays of plans: several plans of one scene side by side, animated with Meshcat's
own recording (time slider, play/pause in the "Animation" controls), and the static HTML of it.

Each plan is a `PlanView` (a label, the planner's `Candidate` and, when it was evaluated with
``record_fps``, its Bullet `Outcome`). It is drawn as its own copy of the scene (the planning
world's illustration geometry: shelf, boxes, PR2 arm) under the Meshcat path
``/drake/illustration`` for the first view (where `views.publish_scene` draws a scene) and
``/drake/illustration_<label>`` for the others, each further copy shifted along -y of W by the
shelf's width plus ``viz.copy_margin``. The camera looks from above and beyond the shelf (+x)
back at the robot, so -y is on the left: the first view is on the right, the next to its left
(Meshcat's "Open Controls" scene tree lists the copies by these names and can hide them).

What moves (frames ``viz.fps`` per second, one timeline for all views):

* with a recording (`recording.Recording`): the arm and the boxes as the evaluation in Bullet
  moved them, and the contact normal forces between the robot and the boxes as arrows (a yellow
  shaft and cone along the force on the box, its tip at the contact point on the box, length
  ``viz.force_scale`` m per N, at most ``viz.max_arrows`` per frame, the largest);
* without one (not evaluated, or rejected before simulating): the arm along the plan's knots
  (linear between them), the boxes where the scene puts them.

Colours: boxes as in the scene file (the target green in the shipped and generated scenes, as
in the paper's figures); a box turns orange (``viz.tipped_rgba``) while it is tilted more than
``evaluation.max_tilt`` and red (``viz.fallen_rgba``) once its centre is off the board
(`scene.grading.tilt_angle`, `scene.grading.off_the_board`: the judge's own), drawn as a
slightly larger overlay box that the animation shows and hides.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.geometry import (
    Box,
    Cylinder,
    Meshcat,
    MeshcatAnimation,
    MeshcatCone,
    MeshcatVisualizer,
    MeshcatVisualizerParams,
    Rgba,
)
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import DiagramBuilder

from drake_clutter.common.config import Config
from drake_clutter.evaluation.outcome import Outcome
from drake_clutter.evaluation.recording import Recording
from drake_clutter.scene.grading import off_the_board, tilt_angle
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import Candidate, robot_positions
from drake_clutter.viz.labels import label_mesh
from drake_clutter.worlds.drake_world import World, build_planning_world

_ARM_AND_FINGERS = slice(1, 10)  # ROBOT_JOINTS within bullet_world.MOTOR_ORDER


@dataclass(frozen=True)
class PlanView:
    """One plan to replay: ``label`` (a Meshcat path element, e.g. the planner's name), the
    candidate (its trajectory) and its evaluation (with a recording, or None)."""

    label: str
    candidate: Candidate
    outcome: Outcome | None = None

    @property
    def recording(self) -> Recording | None:
        """The Bullet recording, if the plan was evaluated with one."""
        return None if self.outcome is None else self.outcome.recording


def view_prefix(index: int, label: str) -> str:
    """The MeshcatVisualizer prefix of the ``index``-th view (under /drake)."""
    return "illustration" if index == 0 else f"illustration_{label}"


def copy_offset(scene: Scene, index: int, config: Config) -> np.ndarray:
    """p_WO (m): where the ``index``-th copy of the scene is shifted to (along -y of W)."""
    return np.array([0.0, -index * (scene.shelf.width + config.viz.copy_margin), 0.0])


@dataclass
class _Copy:
    """One view's drawing: its planning world inside a diagram with its own visualizer."""

    view: PlanView
    path: str  # /drake/<prefix>
    world: World
    diagram: object
    context: object
    plant_context: object
    num_frames: int
    fps: float

    def frame_state(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(robot positions (9), box centres (N, 3), box quaternions wxyz (N, 4)) at frame k
        (the last frame is held after the end)."""
        rec = self.view.recording
        if rec is not None:
            k = min(k, rec.num_frames - 1)
            return rec.robot_q[k, _ARM_AND_FINGERS], rec.box_positions[k], rec.box_quaternions[k]
        traj = self.view.candidate.trajectory
        q = robot_positions(traj.at(traj.times[0] + k / self.fps))  # held after the end
        return q, _rest_positions(self.world.scene), _rest_quaternions(self.world.scene)


def _rest_positions(scene: Scene) -> np.ndarray:
    return np.array([[b.pose[0], b.pose[1], scene.box_center_z(b)] for b in scene.boxes])


def _rest_quaternions(scene: Scene) -> np.ndarray:
    yaw = np.array([b.pose[2] for b in scene.boxes])
    return np.column_stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)])


def _make_copy(scene: Scene, view: PlanView, index: int, config: Config, meshcat: Meshcat,
               variant: str) -> _Copy:
    world = build_planning_world(scene, variant, config.world)
    builder = DiagramBuilder()
    builder.AddSystem(world.diagram)
    prefix = view_prefix(index, view.label)
    params = MeshcatVisualizerParams(prefix=prefix, delete_on_initialization_event=False)
    MeshcatVisualizer.AddToBuilder(builder, world.diagram.GetOutputPort("scene_graph_query"),
                                   meshcat, params)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    if view.recording is not None:
        frames = view.recording.num_frames
    elif view.candidate.trajectory is not None:
        frames = int(np.ceil(view.candidate.trajectory.duration * config.viz.fps)) + 1
    else:
        raise ValueError(f"view '{view.label}' has neither a trajectory nor a recording")
    return _Copy(view, f"/drake/{prefix}", world, diagram, context,
                 world.plant.GetMyMutableContextFromRoot(context), frames, config.viz.fps)


def _pose(copy: _Copy, k: int) -> None:
    """Sets the copy's plant to frame k."""
    q, p_WB, quat = copy.frame_state(k)
    world = copy.world
    world.set_robot_positions(copy.plant_context, q)
    for name, p, wxyz in zip(world.box_names, p_WB, quat, strict=True):
        X_WB = RigidTransform(RotationMatrix(_quat_matrix(wxyz)), p)
        world.plant.SetFreeBodyPose(copy.plant_context, world.box_body(name), X_WB)


def _quat_matrix(wxyz) -> np.ndarray:
    q = np.asarray(wxyz, dtype=float)
    return Quaternion(q / np.linalg.norm(q)).rotation()


# ----------------------------------------------------------------------------- highlights


def box_states(scene: Scene, p_WB: np.ndarray, quats: np.ndarray, config: Config) -> np.ndarray:
    """Per frame and box: 0 upright on the board, 1 tipped (tilted more than
    ``evaluation.max_tilt``), 2 fallen (centre off the board); p_WB (F, N, 3), quats (F, N, 4)."""
    F, N = p_WB.shape[:2]
    R = np.array([_quat_matrix(q) for q in quats.reshape(-1, 4)]).reshape(F, N, 3, 3)
    tipped = tilt_angle(R) > config.evaluation.max_tilt
    fallen = off_the_board(scene, p_WB.reshape(-1, 3)).reshape(F, N)
    return np.where(fallen, 2, np.where(tipped, 1, 0))


def _add_highlights(copy: _Copy, meshcat: Meshcat, animation: MeshcatAnimation,
                    config: Config) -> dict[str, int]:
    """Overlay boxes shown while a box is tipped / fallen; returns how many boxes were
    highlighted at the end, per kind."""
    rec = copy.view.recording
    scene = copy.world.scene
    if rec is None:
        return {"tipped": 0, "fallen": 0}
    states = box_states(scene, rec.box_positions, rec.box_quaternions, config)
    kinds = (("tipped", 1, config.viz.tipped_rgba), ("fallen", 2, config.viz.fallen_rgba))
    pad = 2 * config.viz.highlight_padding
    for i, box in enumerate(scene.boxes):
        for kind, code, rgba in kinds:
            shown = states[:, i] == code
            if not shown.any():
                continue
            path = f"{copy.path}/boxes/{box.name}/highlight_{kind}"
            meshcat.SetObject(path, Box(*(np.asarray(box.size) + pad)), Rgba(*rgba))
            meshcat.SetProperty(path, "visible", False)
            _visibility_track(animation, path, shown)
    return {kind: int(np.sum(states[-1] == code)) for kind, code, _ in kinds}


def _visibility_track(animation: MeshcatAnimation, path: str, shown: np.ndarray) -> None:
    """Keys ``visible`` at frame 0 and wherever it changes."""
    animation.SetProperty(0, path, "visible", bool(shown[0]))
    for k in np.flatnonzero(shown[1:] != shown[:-1]) + 1:
        animation.SetProperty(int(k), path, "visible", bool(shown[k]))


# ----------------------------------------------------------------------------- force arrows


def arrow_frames(rec: Recording, config: Config) -> list[np.ndarray]:
    """Per frame, the contact rows (K, 7) to draw: the ``viz.max_arrows`` largest forces
    above ``viz.min_force`` N."""
    out = []
    for rows in rec.contacts:
        rows = rows[rows[:, 6] >= config.viz.min_force]
        out.append(rows[np.argsort(-rows[:, 6], kind="stable")[:config.viz.max_arrows]])
    return out


def _add_arrows(copy: _Copy, meshcat: Meshcat, animation: MeshcatAnimation,
                config: Config) -> int:
    """Animated force arrows of a recorded view; returns the number of arrow slots."""
    rec = copy.view.recording
    if rec is None:
        return 0
    frames = arrow_frames(rec, config)
    slots = max((len(f) for f in frames), default=0)
    viz = config.viz
    colour = Rgba(*viz.arrow_rgba)
    for j in range(slots):
        path = f"{copy.path}/contact_forces/arrow_{j}"
        # A unit shaft from z = 0 to 1 scaled along z, and a cone tip moved to the shaft's end.
        meshcat.SetObject(f"{path}/shaft/unit", Cylinder(viz.arrow_radius, 1.0), colour)
        meshcat.SetTransform(f"{path}/shaft/unit", RigidTransform([0.0, 0.0, 0.5]))
        tip = viz.arrow_tip_length
        meshcat.SetObject(f"{path}/tip/cone", MeshcatCone(tip, 2 * viz.arrow_radius,
                                                          2 * viz.arrow_radius), colour)
        # MeshcatCone has its apex at the origin and opens along +z: turn it to point along +z.
        meshcat.SetTransform(f"{path}/tip/cone",
                             RigidTransform(RotationMatrix.MakeXRotation(np.pi), [0, 0, tip]))
        meshcat.SetProperty(path, "visible", False)
        shown = np.array([len(f) > j for f in frames])
        _visibility_track(animation, path, shown)
        for k in np.flatnonzero(shown):
            p, n, force = frames[k][j, :3], frames[k][j, 3:6], frames[k][j, 6]
            length = max(force * viz.force_scale, 1e-4)
            # The arrow ends at the contact point: drawn from it, it would hide in the box.
            animation.SetTransform(int(k), path, RigidTransform(
                RotationMatrix.MakeFromOneVector(n, 2), p - length * n))
            animation.SetProperty(int(k), f"{path}/shaft", "scale", [1.0, 1.0, length])
            animation.SetTransform(int(k), f"{path}/tip", RigidTransform([0.0, 0.0, length]))
    return slots


# ----------------------------------------------------------------------------- the replay


@dataclass(frozen=True)
class ReplaySummary:
    """What `record_replay` drew: per view its Meshcat path, frames, arrow slots and the
    highlighted boxes at the end; the animation's length (s)."""

    paths: tuple[str, ...]
    frames: tuple[int, ...]
    arrow_slots: tuple[int, ...]
    highlighted: tuple[dict, ...]
    duration: float


def record_replay(scene: Scene, views: Sequence[PlanView], config: Config, meshcat: Meshcat,
                  variant: str = "capsules") -> ReplaySummary:
    """Draws every view as its own copy of ``scene`` in ``meshcat`` and publishes one
    animation of all of them (module docstring); the camera looks at all copies."""
    if not views:
        raise ValueError("nothing to replay: no plans")
    copies = draw_copies(scene, views, config, meshcat, variant)
    fps = config.viz.fps
    total = max(c.num_frames for c in copies)
    meshcat.StartRecording(frames_per_second=fps, set_visualizations_while_recording=False)
    for k in range(total):
        for copy in copies:
            _pose(copy, k)
            copy.context.SetTime((k + 1e-3) / fps)  # frame k (Meshcat floors time x fps)
            copy.diagram.ForcedPublish(copy.context)
    meshcat.StopRecording()
    animation = meshcat.get_mutable_recording()
    highlighted = tuple(_add_highlights(c, meshcat, animation, config) for c in copies)
    slots = tuple(_add_arrows(c, meshcat, animation, config) for c in copies)
    # Played once, it stays at the last frame (the state the outcome was classified on)
    # instead of snapping back to the scene as first published.
    animation.set_clamp_when_finished(True)
    meshcat.PublishRecording()
    look_at_copies(meshcat, scene, len(copies), config)
    return ReplaySummary(tuple(c.path for c in copies), tuple(c.num_frames for c in copies),
                         slots, highlighted, (total - 1) / fps)


def draw_copies(scene: Scene, views: Sequence[PlanView], config: Config, meshcat: Meshcat,
                variant: str = "capsules") -> list[_Copy]:
    """Draws every view as its own copy of ``scene`` in ``meshcat`` at its first frame, each
    copy shifted by `copy_offset`; returns the copies (`pose_copies` moves them)."""
    if not views:
        raise ValueError("nothing to draw: no plans")
    labels = [v.label for v in views]
    if len(set(labels)) != len(labels):
        raise ValueError(f"view labels must differ, got {labels}")
    copies = [_make_copy(scene, v, i, config, meshcat, variant) for i, v in enumerate(views)]
    for i, copy in enumerate(copies):
        _pose(copy, 0)
        copy.diagram.ForcedPublish(copy.context)  # creates the objects
        meshcat.SetTransform(copy.path, RigidTransform(copy_offset(scene, i, config)))
        add_label(meshcat, scene, i, copy.view.label, config)
    return copies


def add_label(meshcat: Meshcat, scene: Scene, index: int, text: str, config: Config) -> str:
    """Draws ``text`` (`labels.label_mesh`, ``viz.label_height`` tall) in front of the
    ``index``-th copy's shelf, just below its board's front edge, turned to face the camera
    (``viz.camera_offset``), 10 cm before the board; returns its Meshcat path,
    ``/drake/labels/<text>``."""
    offset = np.asarray(config.viz.camera_offset, dtype=float)
    tilt = np.arctan2(offset[2], np.hypot(offset[0], offset[1]))  # the camera's elevation
    cx, cy = scene.shelf.center_xy
    height = config.viz.label_height
    p_WL = np.array([cx + scene.shelf.depth / 2 + 0.1, cy,
                     scene.shelf.top_height - 1.5 * height]) + copy_offset(scene, index, config)
    path = f"/drake/labels/{text}"
    meshcat.SetObject(path, label_mesh(text, height))
    meshcat.SetTransform(path, RigidTransform(RotationMatrix.MakeYRotation(-tilt), p_WL))
    return path


def pose_copies(copies: Sequence[_Copy], k: int) -> None:
    """Poses every copy at frame ``k`` (a copy past its last frame holds it) and publishes."""
    for copy in copies:
        _pose(copy, k)
        copy.diagram.ForcedPublish(copy.context)


def look_at_copies(meshcat: Meshcat, scene: Scene, count: int, config: Config) -> None:
    """Points the camera at the middle of ``count`` copies of the scene, from above and beyond
    the shelf (``viz.camera_offset``), far enough back to see them all."""
    cx, cy = scene.shelf.center_xy
    middle = copy_offset(scene, count - 1, config) / 2
    target = np.array([cx, cy, scene.shelf.top_height]) + middle
    viz = config.viz
    spread = 1.0 + viz.camera_spread * (count - 1)
    meshcat.SetCameraPose(target + spread * np.asarray(viz.camera_offset), target)
