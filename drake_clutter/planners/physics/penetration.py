"""Penetration terms over signed distances: c_static, c_static_hull and c_dynamic.

Penetration (Table I: c_static, c_static_hull, c_dynamic) is `clearance.smooth_penetration` of
the signed distance (linear beyond contact, quadratic inside d_safe), one function for both
planners; its Hessian here is the Gauss-Newton (1/d_safe) J'J of the quadratic part, kept
beyond contact too (the linear part has none, and iLQR needs curvature to take a step).
"""

from __future__ import annotations

import math

import numpy as np

from drake_clutter.phi.state import ARM_DIM
from drake_clutter.planners.clearance import smooth_penetration
from drake_clutter.planners.geometry import SHELF, ArmGeometry, Contact
from drake_clutter.planners.physics.costs import Term


def penetration_term(contacts: list[Contact], d_safe: float, columns: int,
                     box_columns: dict[str, int] | None = None) -> Term:
    """sum over ``contacts`` of smooth_penetration(d_safe - d) as a Term over ``columns``
    numbers: the arm's 8 first, a box's (dtheta, dp) at ``box_columns[name]`` when given."""
    value, grad, hess = 0.0, np.zeros(columns), np.zeros((columns, columns))
    for c in contacts:
        if c.distance >= d_safe:
            continue
        v, slope = smooth_penetration(d_safe - c.distance, d_safe)
        J = distance_row(c, columns, box_columns)
        value += v
        grad -= slope * J
        hess += np.outer(J, J) / d_safe
    return Term(value, grad, hess)


def distance_row(c: Contact, columns: int, box_columns: dict[str, int] | None) -> np.ndarray:
    J = np.zeros(columns)
    J[:ARM_DIM] = c.d_dq
    if box_columns and c.d_dbox is not None and c.obstacle in box_columns:
        start = box_columns[c.obstacle]
        J[start:start + 6] = c.d_dbox
    return J


def segment_penetration(geometry: ArmGeometry, q_a, q_b, substeps: int, d_safe: float,
                        exclude: tuple[str, ...] = (), shelf_only: bool = False,
                        spacing: float = 0.0) -> dict[str, Term]:
    """Mean over ``substeps`` configurations on the segment (q_a, q_b] of the penetration of
    the arm and the shelf ("shelf") and of the arm and the boxes but ``exclude`` ("boxes"),
    boxes fixed, each a Term over (q_a, q_b) (16,): the baseline's approximation of a link's
    convex hull between two knots (c_static_hull, c_dynamic; c_static with ``shelf_only``,
    which leaves "boxes" out). One distance query per configuration serves both parts.
    ``spacing`` (m) > 0 raises the count so that no arm point travels more than about that
    between samples (`ArmGeometry.sweep`): a fast segment cannot carry a finger through the
    board unseen. The count is held fixed in the derivatives."""
    if spacing > 0.0:
        substeps = max(substeps, math.ceil(geometry.sweep(q_a, q_b) / spacing))
    zero = Term(0.0, np.zeros(2 * ARM_DIM), np.zeros((2 * ARM_DIM, 2 * ARM_DIM)))
    out = {"shelf": zero} | ({} if shelf_only else {"boxes": zero})
    obstacles = "shelf" if shelf_only else "all"
    for k in range(1, substeps + 1):
        lam = k / substeps
        q = (1 - lam) * np.asarray(q_a) + lam * np.asarray(q_b)
        found = [c for c in geometry.contacts(q, None, d_safe, obstacles)
                 if c.obstacle not in exclude]
        S = np.hstack([(1 - lam) * np.eye(ARM_DIM), lam * np.eye(ARM_DIM)])
        for kind in out:
            part = [c for c in found if (c.obstacle == SHELF) == (kind == "shelf")]
            term = penetration_term(part, d_safe, ARM_DIM)
            if term.value != 0.0:
                out[kind] = out[kind].plus(term.pulled(S), 1.0 / substeps)
    return out
