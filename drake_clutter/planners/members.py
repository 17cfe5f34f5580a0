"""phi's ensemble members (beyond the paper): the worlds a plan is rolled out in when phi is
read over K perturbed scenes instead of one.

Member 0 is the scene as it is; member k >= 1 is the scene with every box moved and its mass
and friction scaled (`scene.perturbation.perturb_boxes` over the ``phi_judge`` ranges, seeded
with ``[phi_judge.seed, k]``: the planner's seeds, never the judge's); member 1 pairs friction as
Bullet does when ``phi_judge.bullet_friction_member`` is set. The judge in phi rolls out
in these worlds.
"""

from __future__ import annotations

from dataclasses import replace

from drake_clutter.common.config import Config
from drake_clutter.scene.perturbation import BoxPerturbation, perturb_boxes
from drake_clutter.scene.scenes import Scene


def member_world(scene: Scene, config: Config, member: int) -> tuple[Scene, Config]:
    """Member ``member``'s scene and configuration (0: both unchanged; see the module
    docstring)."""
    if member == 0:
        return scene, config
    ens = config.phi_judge
    ranges = BoxPerturbation(ens.position, ens.yaw, ens.mass, ens.friction)
    world = perturb_boxes(scene, ranges, [ens.seed, member])
    if member == 1 and ens.bullet_friction_member:
        config = replace(config, world=replace(config.world, friction_as_bullet=True))
    return world, config
