"""Still pictures of judged plans: a strip of frames of one replay, each frame the scene's
copies (`replay.PlanView`s side by side, as the replay draws them) posed at one instant of the
recording, rendered by headless Chromium from Meshcat's static HTML and laid out with
matplotlib, one panel per instant, captioned with its time.

The frames are posed, not played: each instant is its own static page, so the picture shows
exactly the recorded frame (an animated page's screenshot lands wherever the page's clock is).
The replay's overlays of tipped and fallen boxes and its force arrows are animation tracks and
are not drawn here.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.scene.scenes import Scene
from drake_clutter.viz.replay import PlanView, draw_copies, look_at_copies, pose_copies
from drake_clutter.viz.screenshot import screenshot
from drake_clutter.viz.views import write_static_html


def frame_indices(num_frames: int, count: int) -> list[int]:
    """``count`` frame indices spread evenly from the first frame to the last (both kept)."""
    if num_frames < 1 or count < 1:
        raise ValueError("need at least one frame and one picture")
    return sorted({int(round(k)) for k in np.linspace(0, num_frames - 1, count)})


def colour_crop(images: Sequence[np.ndarray], saturation: float = 0.2, above: float = 0.6,
                below: float = 0.3, margin: float = 0.08) -> tuple[slice, slice]:
    """(rows, columns) of the frames to keep: the box around every pixel whose colour
    channels spread more than ``saturation`` (the shelf and the boxes; not the grey arm, floor
    or sky) in any of ``images`` (H, W, 3+ in [0, 1]), grown by ``above`` of its height upward
    (the arm reaching in), ``below`` of it downward (the planner's name before the board) and
    ``margin`` of its width on either side; all of it if none."""
    colourful = np.zeros(images[0].shape[:2], dtype=bool)
    for image in images:
        rgb = image[..., :3]
        colourful |= (rgb.max(axis=-1) - rgb.min(axis=-1)) > saturation
    rows, cols = np.flatnonzero(colourful.any(axis=1)), np.flatnonzero(colourful.any(axis=0))
    if rows.size == 0:
        return slice(None), slice(None)
    height, width = rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1
    top = max(0, int(rows[0] - above * height))
    bottom = min(colourful.shape[0], int(rows[-1] + below * height) + 1)
    left = max(0, int(cols[0] - margin * width))
    right = min(colourful.shape[1], int(cols[-1] + margin * width) + 1)
    return slice(top, bottom), slice(left, right)


def frame_strip(scene: Scene, views: Sequence[PlanView], config: Config, png: str | Path,
                count: int = 4, title: str = "", variant: str = "capsules",
                window: tuple[int, int] = (960, 720)) -> Path:
    """Writes ``png``: ``count`` frames of the views' replay (evenly spread over the longest
    recording, the last one the state the judge classified), left to right and, from 4 frames
    on, in two rows, cropped to the shelves (`colour_crop`), each captioned
    with its time (s) and, under the strip, which copy is which planner (right to left, as the
    replay draws them); returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from pydrake.geometry import Meshcat

    meshcat = Meshcat()
    copies = draw_copies(scene, views, config, meshcat, variant)
    look_at_copies(meshcat, scene, len(copies), config)
    total = max(c.num_frames for c in copies)
    frames = frame_indices(total, count)
    images = []
    with tempfile.TemporaryDirectory() as folder:
        for k in frames:
            pose_copies(copies, k)
            page = write_static_html(meshcat, Path(folder) / f"frame_{k}.html")
            images.append(plt.imread(screenshot(page, Path(folder) / f"frame_{k}.png", window)))
    images = [image[40:] for image in images]  # below Meshcat's "Open Controls" bar
    rows, cols = colour_crop(images)
    height, width = images[0][rows, cols].shape[:2]
    columns = (len(frames) + 1) // 2 if len(frames) >= 4 else len(frames)
    lines = -(-len(frames) // columns)
    panel = 6.0
    figure, axes = plt.subplots(lines, columns, squeeze=False, figsize=(
        panel * columns, lines * (panel * height / width + 0.4) + 0.6))
    for ax in axes.flat:
        ax.axis("off")
    for ax, k, image in zip(axes.flat, frames, images, strict=False):
        ax.imshow(image[rows, cols])
        ax.set_title(f"t = {k / config.viz.fps:.1f} s", fontsize=11)
    sides = ("right", "left") if len(views) == 2 else [f"copy {i}" for i in range(len(views))]
    legend = ", ".join(f"{side}: {v.label} ({v.outcome.kind if v.outcome else 'not judged'})"
                       for side, v in zip(sides, views, strict=False))
    figure.suptitle(f"{title}\n{legend}" if title else legend, fontsize=11)
    figure.tight_layout()
    png = Path(png)
    figure.savefig(png, dpi=100)
    plt.close(figure)
    return png
