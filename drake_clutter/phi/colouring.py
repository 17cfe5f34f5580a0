"""Columns of phi's Jacobians and how a group of them is evaluated (Sec. V's finite differences,
made cheap by `derivatives.PhiDynamics`): which columns and rows each interaction node (the arm,
each kept box) owns, connected components of the interaction graph, Curtis-Powell-Reid colouring
(columns of different components perturbed together), and one group's difference quotients by
finite differences or AutoDiffXd directions. Tangent coordinates (`state.StateLayout`).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from drake_clutter.phi.autodiff import AutoDiffPhi
from drake_clutter.phi.dynamics import ARM_NODE, PhiBase
from drake_clutter.phi.state import ARM_DIM, BOX_TANGENT, NU, StateLayout

# ----------------------------------------------------------------------------- columns


def node_columns(layout: StateLayout, node: int) -> list[int]:
    """Columns of [dx, du] (ndx + nu) owned by an interaction node."""
    if node == ARM_NODE:
        return list(range(ARM_DIM)) + list(range(layout.ndx, layout.ndx + NU))
    start = ARM_DIM + BOX_TANGENT * (node - 1)
    return list(range(start, start + BOX_TANGENT))


def node_rows(layout: StateLayout, node: int) -> np.ndarray:
    """Tangent rows of an interaction node."""
    if node == ARM_NODE:
        return np.arange(ARM_DIM)
    return np.arange(ARM_DIM + BOX_TANGENT * (node - 1), ARM_DIM + BOX_TANGENT * node)


def node_output_rows(layout: StateLayout, node: int) -> np.ndarray:
    """Rows of an interaction node in phi's output [dx' (ndx), f (1 + n)]: its tangent rows
    and its contact-force entry (`dynamics.Phi.contact_forces`)."""
    return np.append(node_rows(layout, node), layout.ndx + node)


def components(num_nodes: int, edges) -> list[list[int]]:
    """Connected components (sorted node lists) of the interaction graph over the arm and
    the kept boxes (edges to frozen boxes, negative nodes, are static contacts: ignored)."""
    edges = [(a, b) for a, b in edges if a >= 0 and b >= 0]
    rows = [a for a, _ in edges]
    cols = [b for _, b in edges]
    graph = coo_matrix((np.ones(len(edges)), (rows, cols)), shape=(num_nodes, num_nodes))
    count, labels = connected_components(graph, directed=False)
    return [sorted(np.flatnonzero(labels == c).tolist()) for c in range(count)]


def colour_groups(column_lists: list[list[int]]) -> list[list[int]]:
    """Groups of columns to perturb together: group g takes the g-th column of every list
    (the lists belong to different components, so no row sees two of a group's columns)."""
    depth = max((len(c) for c in column_lists), default=0)
    return [[cols[g] for cols in column_lists if g < len(cols)] for g in range(depth)]


# ----------------------------------------------------------------------------- evaluation


def perturbed(layout: StateLayout, x, u, columns, step: float):
    """(x (+) step e_cols, u + step e_cols) for tangent/control column indices."""
    dx = np.zeros(layout.ndx + NU)
    dx[list(columns)] = step
    return layout.retract(x, dx[:layout.ndx]), np.asarray(u, dtype=float) + dx[layout.ndx:]


def group_differences(phi: PhiBase, x, u, nominal, groups, step: float, scheme: str) -> np.ndarray:
    """Difference quotients (len(groups), ndx + 1 + n) of phi's output [x' (tangent), contact
    forces f] for each group of columns perturbed together: forward (phi(x + h e) (-)
    phi(x)) / h about ``nominal`` = (x', f) (None: phi's own step from (x, u)) or central
    (phi(x + h e) (-) phi(x - h e)) / 2h. A failed evaluation gives a row of NaN."""
    layout = phi.layout
    if scheme != "central" and nominal is None:
        nominal = phi.step_forces(x, u)
    out = np.empty((len(groups), layout.ndx + phi.num_forces))
    for g, cols in enumerate(groups):
        x_plus, f_plus = phi.step_forces(*perturbed(layout, x, u, cols, step))
        if scheme == "central":
            x_minus, f_minus = phi.step_forces(*perturbed(layout, x, u, cols, -step))
            width = 2 * step
        else:
            (x_minus, f_minus), width = nominal, step
        out[g] = np.concatenate([layout.difference(x_plus, x_minus), f_plus - f_minus]) / width
    return out


def dense_jacobians(phi: PhiBase, x, u, step: float | None = None, scheme: str | None = None,
                    forces: bool = False):
    """Brute force: every column perturbed alone; (A (ndx, ndx), B (ndx, nu)) in tangent
    coordinates, and with ``forces`` also the contact forces' (Fx (1 + n, ndx), Fu (1 + n,
    nu)); ndx + nu + 1 phi evaluations (2 (ndx + nu) central). Step and scheme default to
    phi's configuration."""
    layout = phi.layout
    step = phi.spec.config.fd_step if step is None else step
    scheme = phi.spec.config.fd_scheme if scheme is None else scheme
    nominal = phi.step_forces(x, u) if scheme == "forward" else None
    cols = [[c] for c in range(layout.ndx + NU)]
    D = group_differences(phi, x, u, nominal, cols, step, scheme).T
    ndx = layout.ndx
    jacobians = (D[:ndx, :ndx], D[:ndx, ndx:])
    return jacobians + (D[ndx:, :ndx], D[ndx:, ndx:]) if forces else jacobians


def group_seeds(layout: StateLayout, groups) -> np.ndarray:
    """Seed directions ((ndx + nu) x len(groups)): column g sums the unit columns of group g."""
    S = np.zeros((layout.ndx + NU, len(groups)))
    for g, cols in enumerate(groups):
        S[list(cols), g] = 1.0
    return S


def group_autodiff(autodiff: AutoDiffPhi, x, u, groups) -> np.ndarray:
    """`group_differences`' result (len(groups), ndx + 1 + n) by AutoDiffXd: exact directional
    derivatives of [x' (tangent), f] along each group's summed columns (NaN rows on failure)."""
    return autodiff.directional(x, u, group_seeds(autodiff.phi.layout, groups)).T
