"""A recording of the Bullet replay (Sec. III's judge), for watching it: frames at a fixed rate.

`judge.evaluate(..., record_fps=30)` fills a `Recorder` while it replays a plan and returns
the `Recording` in ``Outcome.recording``. Recording only reads the simulator's state (poses,
joint positions, the contact points of Bullet's last solve), so the outcome is the same with or
without it.

A frame holds, at time ``times[k]`` (s since the replay started):

* ``box_positions[k]`` (N, 3): box centres p_WB in W (m), scene order;
* ``box_quaternions[k]`` (N, 4): box orientations R_WB as unit quaternions (w, x, y, z);
* ``robot_q[k]`` (10,): the robot joints in ``bullet_world.MOTOR_ORDER`` (torso lift m, seven
  arm joints rad, two finger slides m);
* ``contacts[k]`` (K, 7): every contact point between the robot (arm or gripper) and a box:
  the point on the box p_WC (m, W), the unit normal n_W along which the robot pushes the box
  (from the robot into the box), the normal force (N, >= 0), and the box's index in
  ``contact_boxes[k]`` (K,).

Frame 0 is the arm at the plan's first knot before the first step; after that a frame is taken
at the first simulator update at or after every multiple of 1 / ``fps``; the last frame is the
state the outcome was classified on (where the evaluation stopped: a kinematic failure, or the
boxes at rest). A plan rejected before simulating (joint limits) has no recording; the optional
grasp-and-lift check is not recorded.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drake_clutter.worlds import bullet_world as bw


@dataclass(frozen=True, eq=False)
class Recording:
    """Frames of a Bullet replay (see the module docstring for shapes, frames and units)."""

    fps: float
    box_names: tuple[str, ...]
    times: np.ndarray
    box_positions: np.ndarray
    box_quaternions: np.ndarray
    robot_q: np.ndarray
    contacts: tuple[np.ndarray, ...]
    contact_boxes: tuple[np.ndarray, ...]

    @property
    def num_frames(self) -> int:
        """Number of frames."""
        return len(self.times)

    @property
    def duration(self) -> float:
        """s from the first to the last frame."""
        return float(self.times[-1] - self.times[0]) if len(self.times) else 0.0

    def largest_contact_force(self) -> float:
        """The largest single normal force (N) between the robot and a box in any frame."""
        return max((float(c[:, 6].max()) for c in self.contacts if len(c)), default=0.0)


@dataclass
class Recorder:
    """Collects `Recording` frames from a `bullet_world.BulletWorld` at ``fps`` frames per
    second of simulated time."""

    fps: float
    times: list = field(default_factory=list)
    positions: list = field(default_factory=list)
    quaternions: list = field(default_factory=list)
    robot_q: list = field(default_factory=list)
    contacts: list = field(default_factory=list)
    contact_boxes: list = field(default_factory=list)

    def __post_init__(self):
        if not self.fps > 0:
            raise ValueError(f"the recording rate must be positive, got {self.fps!r} fps")

    def sample(self, world: bw.BulletWorld, t: float) -> None:
        """Takes a frame at simulated time ``t`` (s) if one is due (the first call always)."""
        due = len(self.times) / self.fps
        if self.times and t < due - 1e-9:
            return
        self._take(world, t)

    def _take(self, world: bw.BulletWorld, t: float) -> None:
        p_WB, quats = _box_states(world)
        points, boxes = robot_box_contacts(world)
        self.times.append(float(t))
        self.positions.append(p_WB)
        self.quaternions.append(quats)
        self.robot_q.append(bw.joint_positions(world))
        self.contacts.append(points)
        self.contact_boxes.append(boxes)

    def finish(self, world: bw.BulletWorld, t: float) -> Recording:
        """The recording, with a last frame of the state at ``t`` (s) unless the last frame
        taken is at ``t`` already (the end of the replay falls between frames)."""
        if not self.times or self.times[-1] < t - 1e-9:
            self._take(world, t)
        n = len(world.box_names)
        return Recording(
            self.fps, tuple(world.box_names), np.array(self.times),
            np.array(self.positions).reshape(-1, n, 3),
            np.array(self.quaternions).reshape(-1, n, 4),
            np.array(self.robot_q).reshape(-1, len(bw.MOTOR_ORDER)),
            tuple(self.contacts), tuple(self.contact_boxes))


def _box_states(world: bw.BulletWorld) -> tuple[np.ndarray, np.ndarray]:
    """Box centres (N, 3) and quaternions (N, 4, w first), read without touching the state."""
    positions, quats = [], []
    for body in world.boxes:
        p, (x, y, z, w) = bw.pb.getBasePositionAndOrientation(body, physicsClientId=world.client)
        positions.append(p)
        quats.append((w, x, y, z))
    return np.array(positions).reshape(-1, 3), np.array(quats).reshape(-1, 4)


def robot_box_contacts(world: bw.BulletWorld) -> tuple[np.ndarray, np.ndarray]:
    """The robot-box contact points of Bullet's last solve: rows (p_WC on the box, unit normal
    from the robot into the box, normal force N), shape (K, 7), and the boxes' scene indices."""
    rows, boxes = [], []
    for point in bw.pb.getContactPoints(bodyA=world.robot, physicsClientId=world.client):
        i = world.box_index.get(point[2])
        if i is None:
            continue
        # Bullet's contactNormalOnB points from B (the box) to A (the robot).
        rows.append((*point[6], *(-np.asarray(point[7])), max(point[9], 0.0)))
        boxes.append(i)
    return np.array(rows, dtype=float).reshape(-1, 7), np.array(boxes, dtype=int)
