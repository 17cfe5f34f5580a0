"""The planning worlds of one scene, each built once and passed down (shared by the planners).

A Drake planning world is a diagram with the arm, the shelf and the boxes; building one costs
far more than a query in it. `PlanningContext` builds each world a planner needs on first use
and hands the same one to every approach angle and every stage after that:

* `PlanningContext.arm`: the arm in a geometry variant with the boxes at rest
  (`geometry.ArmGeometry`), for the geometric checks (`geometry.path_depths`), the judge in
  phi's readings and the kinematic stages. Callers never move its boxes: a check reads the
  boxes "where the geometry last put them", and here that is always their rest.
* `PlanningContext.fresh_arm`: a new arm of its own for a phi stage's objective, which moves
  the boxes to phi's poses (the one other place an arm is built).
* `PlanningContext.clearance`: arm-vs-shelf distances without the boxes
  (`clearance.ShelfClearance` over `approach.static_planning_world`).
* `PlanningContext.baseline_at`: Sec. IV's prepared solvers at a grasp height
  (`baseline.prepare`), for the straight starts at other heights (`starts.height_candidates`);
  each call returns them with no neighbour's IK solution, as a fresh `prepare` would.

A worker process builds its own context: Drake's worlds do not cross processes.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from drake_clutter.common.config import Config
from drake_clutter.planners import baseline
from drake_clutter.planners.approach import static_planning_world
from drake_clutter.planners.clearance import ShelfClearance
from drake_clutter.planners.geometry import ArmGeometry
from drake_clutter.scene.scenes import Scene


@dataclass
class PlanningContext:
    """One scene's planning worlds under one configuration (module docstring)."""

    scene: Scene
    config: Config
    _arms: dict = field(default_factory=dict, repr=False)
    _clearance: ShelfClearance | None = field(default=None, repr=False)
    _baselines: dict = field(default_factory=dict, repr=False)

    def with_config(self, config: Config) -> PlanningContext:
        """The same scene's worlds under other settings: the arms and the clearance are
        shared (they do not depend on the configuration); Sec. IV's prepared solvers only
        where ``config.baseline`` is the same."""
        same = config.baseline == self.config.baseline
        return PlanningContext(self.scene, config, self._arms, self._clearance,
                               self._baselines if same else {})

    def arm(self, variant: str = "capsules") -> ArmGeometry:
        """The arm in ``variant`` ("capsules", "sphere_gripper", "evaluation") with the boxes at
        rest, built on first use; its boxes must not be moved."""
        if variant not in self._arms:
            self._arms[variant] = self.fresh_arm(variant)
        return self._arms[variant]

    def fresh_arm(self, variant: str = "capsules") -> ArmGeometry:
        """A new arm in ``variant`` with the boxes at rest, the caller's own to move."""
        return ArmGeometry(self.scene, variant)

    @property
    def clearance(self) -> ShelfClearance:
        """Arm-vs-shelf distances in the scene's planning world without boxes."""
        if self._clearance is None:
            self._clearance = ShelfClearance(static_planning_world(self.scene))
        return self._clearance

    def baseline_at(self, fraction: float):
        """Sec. IV's prepared solvers (`baseline.prepare`) with the grasp height at ``fraction``
        of the target's height, built once per fraction; no neighbour's IK solution carried
        over from an earlier call."""
        if fraction not in self._baselines:
            cfg = replace(self.config.baseline, grasp_height_fraction=fraction)
            self._baselines[fraction] = baseline.prepare(self.scene, cfg)
        return replace(self._baselines[fraction], previous=[])
