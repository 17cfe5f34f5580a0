"""Fixtures the planners' tests share: fig5 and its baseline path at alpha 0.3."""

from __future__ import annotations

import numpy as np
import pytest

from drake_clutter.common.config import Config
from drake_clutter.scene import scenes


@pytest.fixture(scope="module")
def scene():
    return scenes.load_shipped_scene("fig5_large_small")


@pytest.fixture(scope="module")
def baseline_path(scene):
    """The baseline's knot path (T + 1, 8) on fig5 at alpha 0.3."""
    from drake_clutter.planners.baseline import plan_baseline

    (candidate,) = plan_baseline(scene, Config().baseline, alphas=[0.3])
    assert candidate.ok, candidate.reason
    return np.asarray(candidate.trajectory.q, float)
