"""Words in a Meshcat scene: Meshcat has no text object, so a word is matplotlib's outline of it
(`matplotlib.textpath.TextPath`) sampled on a grid, each row's filled runs drawn as flat
quads of one `TriangleSurfaceMesh` (double-sided), standing upright in a vertical plane.

The replay puts one in front of each copy's shelf (`replay.add_label`), naming the planner whose
plan it shows.
"""

from __future__ import annotations

import numpy as np
from matplotlib.font_manager import FontProperties
from matplotlib.path import Path as MplPath
from matplotlib.textpath import TextPath
from pydrake.geometry import SurfaceTriangle, TriangleSurfaceMesh

FONT = FontProperties(family="DejaVu Sans", weight="bold")  # ships with matplotlib


def text_bitmap(text: str, rows: int) -> np.ndarray:
    """(rows, columns) booleans, row 0 at the top: the cells of a grid of ``rows`` rows over
    the text's height whose centres fall inside its glyphs (holes left open: a point is inside
    when an odd number of the outline's closed polygons hold it)."""
    if not text.strip() or rows < 1:
        raise ValueError("need some text and at least one row")
    path = TextPath((0, 0), text, size=1.0, prop=FONT)
    box = path.get_extents()
    cell = box.height / rows
    columns = max(1, int(np.ceil(box.width / cell)))
    xs = box.x0 + (np.arange(columns) + 0.5) * cell
    ys = box.y0 + (np.arange(rows) + 0.5) * cell
    points = np.column_stack([g.ravel() for g in np.meshgrid(xs, ys)])
    inside = np.zeros(len(points), dtype=bool)
    for polygon in path.to_polygons():
        inside ^= MplPath(polygon).contains_points(points)
    return inside.reshape(rows, columns)[::-1]


def _runs(row: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True cells in a row."""
    padded = np.concatenate([[False], row, [False]]).astype(int)
    edges = np.flatnonzero(np.diff(padded))
    return list(zip(edges[::2], edges[1::2], strict=True))


def label_mesh(text: str, height: float, rows: int = 24) -> TriangleSurfaceMesh:
    """The word as a flat mesh in the plane x = 0 of its own frame (m): reading along +y, up
    along +z, its baseline-to-top cell grid ``height`` tall, centred on the origin in y and
    standing on z = 0. Seen from +x it reads left to right."""
    bitmap = text_bitmap(text, rows)
    cell = height / rows
    width = bitmap.shape[1] * cell
    vertices, triangles = [], []
    for r, row in enumerate(bitmap):
        z0, z1 = height - (r + 1) * cell, height - r * cell
        for start, stop in _runs(row):
            y0, y1 = start * cell - width / 2, stop * cell - width / 2
            base = len(vertices)
            vertices += [np.array([0.0, y, z]) for y, z in ((y0, z0), (y1, z0), (y1, z1),
                                                            (y0, z1))]
            triangles += [SurfaceTriangle(base, base + 1, base + 2),
                          SurfaceTriangle(base, base + 2, base + 3)]
    return TriangleSurfaceMesh(triangles, vertices)
