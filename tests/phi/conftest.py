"""phi's shared scene: a 10-box bookshelf and the straight reach into it (IK solved once per
module). A module picks its scene's seed with ``SCENE_SEED`` (default 0)."""

from __future__ import annotations

import pytest

from drake_clutter.scene.generators import generate_scene
from drake_clutter.testing.reach_paths import straight_reach


@pytest.fixture(scope="module")
def scene10(request):
    return generate_scene("bookshelf", 10, seed=getattr(request.module, "SCENE_SEED", 0))


@pytest.fixture(scope="module")
def reach10(scene10):
    path = straight_reach(scene10)
    assert path is not None
    return path
