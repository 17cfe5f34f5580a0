"""Penetration terms over signed distances: c_static, c_static_hull, c_dynamic and c_press.

Penetration (Table I: c_static, c_static_hull, c_dynamic) is `clearance.smooth_penetration` of
the signed distance (linear beyond contact, quadratic inside d_safe), one function for both
planners; its Hessian here is the Gauss-Newton (1/d_safe) J'J of the quadratic part, kept
beyond contact too (the linear part has none, and iLQR needs curvature to take a step).

c_press (ours) is the same penetration summed over the arm-box pairs whose contact normal
(from the box to the arm, W) points up by more than a threshold: the arm over a box's top,
which in the judge's hard contact presses the box into the board with hundreds of newtons
(Sec. III's kinematic failure: "box pushed into static geometry") while the compliant phi
reads a few. It is a function of the arm alone: the box cannot make way downwards.
"""

from __future__ import annotations

import math

import numpy as np

from drake_clutter.phi.state import ARM_DIM
from drake_clutter.planners.clearance import smooth_penetration
from drake_clutter.planners.geometry import SHELF, ArmGeometry, Contact, pressing
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


def deep_penetration_term(contacts: list[Contact], depth: float, columns: int) -> Term:
    """sum over ``contacts`` of 1/2 (-d - depth)^2 where the arm sinks deeper than ``depth``
    (m) into the obstacle: the phi stages' steep part of c_static (Gauss-Newton Hessian J'J,
    exact beyond ``depth``), as a Term over ``columns`` numbers (the arm's 8 first)."""
    value, grad, hess = 0.0, np.zeros(columns), np.zeros((columns, columns))
    for c in contacts:
        excess = -c.distance - depth
        if excess <= 0.0:
            continue
        J = distance_row(c, columns, None)
        value += 0.5 * excess * excess
        grad -= excess * J
        hess += np.outer(J, J)
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
                        deep: tuple[float, float] = (0.0, 0.0),
                        spacing: float = 0.0, press_z: float | None = None
                        ) -> dict[str, Term]:
    """Mean over ``substeps`` configurations on the segment (q_a, q_b] of the penetration of
    the arm and the shelf ("shelf") and of the arm and the boxes but ``exclude`` ("boxes"),
    boxes fixed, each a Term over (q_a, q_b) (16,): the baseline's approximation of a link's
    convex hull between two knots (c_static_hull, c_dynamic; c_static with ``shelf_only``,
    which leaves "boxes" out). ``deep`` = (weight, depth): the shelf part adds weight x
    `deep_penetration_term` (depth, m). With ``press_z``, "press": c_press over every box
    (``exclude`` too) whose normal's up component exceeds it. One distance query per
    configuration serves them all (the boxes' distances only when a part needs them).
    ``spacing`` (m) > 0 raises the count so that no arm point travels more than about that
    between samples (`ArmGeometry.sweep`): a fast segment cannot carry a finger through the
    board unseen. The count is held fixed in the derivatives."""
    if spacing > 0.0:
        substeps = max(substeps, math.ceil(geometry.sweep(q_a, q_b) / spacing))
    zero = Term(0.0, np.zeros(2 * ARM_DIM), np.zeros((2 * ARM_DIM, 2 * ARM_DIM)))
    out = ({"shelf": zero} | ({} if shelf_only else {"boxes": zero})
           | ({"press": zero} if press_z is not None else {}))
    obstacles = "shelf" if shelf_only and press_z is None else "all"
    for k in range(1, substeps + 1):
        lam = k / substeps
        q = (1 - lam) * np.asarray(q_a) + lam * np.asarray(q_b)
        everything = geometry.contacts(q, None, d_safe, obstacles)
        found = [c for c in everything if c.obstacle not in exclude]
        S = np.hstack([(1 - lam) * np.eye(ARM_DIM), lam * np.eye(ARM_DIM)])
        for kind in out:
            if kind == "press":
                term = press_term(everything, d_safe, ARM_DIM, press_z)
            else:
                part = [c for c in found if (c.obstacle == SHELF) == (kind == "shelf")]
                term = penetration_term(part, d_safe, ARM_DIM)
            if kind == "shelf" and deep[0] > 0.0:
                term = term.plus(deep_penetration_term(part, deep[1], ARM_DIM), deep[0])
            if term.value != 0.0:
                out[kind] = out[kind].plus(term.pulled(S), 1.0 / substeps)
    return out


def press_term(contacts: list[Contact], d_safe: float, columns: int, normal_z: float) -> Term:
    """c_press: `penetration_term` of the arm-box pairs of ``contacts`` that press down
    (`pressing`), over ``columns`` numbers (the arm's 8 first; the boxes' columns get none)."""
    return penetration_term(pressing(contacts, normal_z), d_safe, columns)
