"""Fixtures the rearrange planner's tests share: a box crowding the target's pre-grasp pose on
an otherwise empty bookshelf, and the baseline's reach into it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from drake_clutter.common.config import Config
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.registry import run_planners
from drake_clutter.scene.generators import generate_scene
from drake_clutter.scene.scenes import validate_scene
from drake_clutter.testing.handmade import make_box

ANGLE = 7  # alpha 0.07 rad: the reach's open gripper enters the side box by about 37 mm


@pytest.fixture(scope="package")
def crowded():
    """The target of bookshelf 1 (seed 0) and a 6 x 6 x 12 cm box 7 cm beside it."""
    base = generate_scene("bookshelf", 1, 0, Config().generator)
    target = base.target_box
    side = make_box("side", (0.06, 0.06, 0.12), (target.pose[0], target.pose[1] + 0.07))
    return validate_scene(replace(base, name="crowded", boxes=(target, side)))


@pytest.fixture(scope="package")
def alone(crowded):
    """The crowded scene without its side box."""
    return validate_scene(replace(crowded, name="alone", boxes=(crowded.target_box,)))


@pytest.fixture(scope="package")
def context(crowded):
    return PlanningContext(crowded, Config())


@pytest.fixture(scope="package")
def reach(crowded):
    """The baseline's candidate at `ANGLE` on the crowded scene."""
    (candidate,) = run_planners(crowded, Config(), ["baseline"], angles=[ANGLE])["baseline"]
    assert candidate.ok, candidate.reason
    return candidate


@pytest.fixture(scope="package")
def reach_q(reach):
    return np.asarray(reach.trajectory.q, float)
