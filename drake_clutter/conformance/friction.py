"""Per-body friction coefficients that realise a scenario's pair coefficients in each engine.

Engines combine two bodies' coefficients a, b into the pair's differently:

* Drake: 2ab / (a + b), i.e. 1/a + 1/b = 2 / mu_ab: linear in the reciprocals, which must be
  positive;
* Bullet: ab, i.e. log a + log b = log mu_ab: linear in the logarithms, always positive;
* MuJoCo: max(a, b) by default; the suite gives MuJoCo every pair explicitly (``<pair>``), so it
  needs no per-body coefficient.

Both linear systems are solved in the least-squares sense, nudged toward equal coefficients
where the pairs leave freedom; a solution whose pairs miss the scenario's by more than
``TOLERANCE`` (relative) or whose Drake coefficients are not positive cannot be realised and
raises `UnrealisableFriction`.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear

from drake_clutter.conformance.scenarios import Scenario
from drake_clutter.worlds.drake_world import drake_pair_friction

TOLERANCE = 1e-6  # relative error allowed on a realised pair
_SMALLEST_COEFFICIENT = 1e-3
_LARGEST_COEFFICIENT = 1e3


class UnrealisableFriction(ValueError):
    """An engine's combination rule cannot give the scenario's pair coefficients."""


def _system(scenario: Scenario) -> tuple[list[str], np.ndarray, list[float]]:
    bodies = list(scenario.bodies)
    rows, values = [], []
    for a, b, mu in scenario.friction:
        if not mu > 0:
            raise UnrealisableFriction(f"{scenario.name}: pair {a}-{b} must be positive, "
                                       f"got {mu!r}")
        row = np.zeros(len(bodies))
        row[bodies.index(a)] += 1.0
        row[bodies.index(b)] += 1.0
        rows.append(row)
        values.append(mu)
    return bodies, np.array(rows), values


def _solve(a: np.ndarray, b: np.ndarray, prior: float, lower: float, upper: float) -> np.ndarray:
    """Least squares A x = b with a weak pull of x toward ``prior`` within [lower, upper]."""
    weight = 1e-6
    a_aug = np.vstack([a, weight * np.eye(a.shape[1])])
    b_aug = np.concatenate([b, weight * np.full(a.shape[1], prior)])
    return lsq_linear(a_aug, b_aug, bounds=(lower, upper), lsmr_tol="auto").x


def drake_coefficients(scenario: Scenario) -> dict[str, float]:
    """Body -> Coulomb coefficient whose Drake pairs 2ab / (a + b) are the scenario's."""
    bodies, a, mus = _system(scenario)
    reciprocal = _solve(a, 2.0 / np.array(mus), float(np.mean(1.0 / np.array(mus))),
                        1.0 / _LARGEST_COEFFICIENT, 1.0 / _SMALLEST_COEFFICIENT)
    coefficients = dict(zip(bodies, 1.0 / reciprocal, strict=True))
    _check(scenario, coefficients, drake_pair_friction, "Drake")
    return coefficients


def bullet_coefficients(scenario: Scenario) -> dict[str, float]:
    """Body -> lateral friction whose Bullet pairs (products) are the scenario's."""
    bodies, a, mus = _system(scenario)
    logs = _solve(a, np.log(mus), float(np.mean(np.log(mus))) / 2,
                  np.log(_SMALLEST_COEFFICIENT), np.log(_LARGEST_COEFFICIENT))
    coefficients = dict(zip(bodies, np.exp(logs), strict=True))
    _check(scenario, coefficients, lambda x, y: x * y, "Bullet")
    return coefficients


def _check(scenario: Scenario, coefficients: dict[str, float], combine, engine: str) -> None:
    for a, b, mu in scenario.friction:
        got = combine(coefficients[a], coefficients[b])
        if abs(got - mu) > TOLERANCE * mu:
            raise UnrealisableFriction(
                f"{scenario.name}: {engine} cannot realise the {a}-{b} pair {mu:g} together with "
                f"the other pairs (closest {got:.6g})")
