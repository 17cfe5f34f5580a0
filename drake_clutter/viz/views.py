"""Meshcat views: a scene with the parked arm, served live or written as static HTML.

Everything goes through Drake's own Meshcat (``pydrake.geometry.Meshcat``), which serves on
localhost from inside this process. No module-level Meshcat: callers create one and pass it,
or let `show_scene` make its own.
"""

from __future__ import annotations

import base64
import re
import time
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat

from drake_clutter.common.config import Config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.scene.scenes import Scene
from drake_clutter.worlds.drake_world import build_planning_world, park_positions


def publish_scene(scene: Scene, config: Config, meshcat: Meshcat,
                  variant: str = "capsules", q_robot=None) -> None:
    """Draws ``scene`` in ``meshcat`` with the arm at ``q_robot`` (default: parked)."""
    world = build_planning_world(scene, variant, config.world, meshcat=meshcat)
    context = world.diagram.CreateDefaultContext()
    plant_context = world.plant.GetMyMutableContextFromRoot(context)
    q = park_positions(world, config.world) if q_robot is None else q_robot
    world.set_robot_positions(plant_context, q)
    world.diagram.ForcedPublish(context)
    look_at_shelf(meshcat, scene)


def look_at_shelf(meshcat: Meshcat, scene: Scene) -> None:
    """Points Meshcat's camera at the shelf from behind and to the right of the robot."""
    cx, cy = scene.shelf.center_xy
    target = np.array([cx, cy, scene.shelf.top_height])
    meshcat.SetCameraPose(target + np.array([-0.6, -1.5, 0.8]), target)


def write_static_html(meshcat: Meshcat, path: str | Path) -> Path:
    """Writes Meshcat's current scene as a self-contained HTML file; returns the path."""
    path = Path(path)
    try:
        path.write_text(meshcat.StaticHtml(), encoding="utf-8")
    except OSError as exc:
        raise InputError(path, "--html", f"cannot write the HTML file: {exc.strerror}") from None
    return path


_EMBEDDED = re.compile(r'fetch\("data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"\)')
_PATH = re.compile(rb"/drake/[A-Za-z0-9_/.\-]+")


def static_html_paths(html: str) -> set[str]:
    """The Meshcat scene-tree paths that a static HTML file draws (for checks and tests)."""
    paths: set[str] = set()
    for blob in _EMBEDDED.findall(html):
        paths.update(p.decode() for p in _PATH.findall(base64.b64decode(blob)))
    return paths


def show_scene(scene: Scene, config: Config, variant: str = "capsules",
               html: str | Path | None = None, wait: bool = True) -> Meshcat:
    """Shows a scene and the parked arm in Meshcat and prints the URL.

    With ``html`` the view is written to that file instead. With ``wait`` the function keeps
    serving until interrupted (Ctrl-C).
    """
    meshcat = Meshcat()
    publish_scene(scene, config, meshcat, variant)
    if html is not None:
        path = write_static_html(meshcat, html)
        print(f"wrote {path}")
        return meshcat
    print(f"Meshcat: {meshcat.web_url()}  (scene '{scene.name}')", flush=True)
    if wait:
        print("serving; press Ctrl-C to stop", flush=True)
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            pass
    return meshcat
