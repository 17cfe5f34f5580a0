"""A jam measure that does not depend on the contact's stiffness: how far the arm is commanded
into a box that a rigid world would not let move.

A compliant phi prices a jam at a few newtons (its boxes and its PD arm give way), where the
judge's hard contact reads hundreds: the force depends on the stiffness, so it cannot be the
measure. The geometry of the contacts does not. At a sub-step, a box the arm touches is
**blocked** when the push cannot move it in a rigid world: the direction it is pushed in (the
contact normal, from the arm into the box) is held by the friction cones of its contacts with
static geometry (the shelf's board and walls, frozen boxes), or with boxes that are blocked in
turn under the push it passes on (quasi-static, translation only, weight neglected: the arm is
kinematic, so its force grows without bound). On a board alone a horizontal push is never
blocked (the board's cone is about +z); a push down, or into a wall, is.

The measure of a blocked box is the arm's **commanded** approach into it: the speed of the
contact point on the arm, at the commanded joint velocities (not the PD arm's lagging ones),
along the push direction, integrated over the blocked sub-steps (m). A rigid box would need a
force that grows with it at the judge's contact stiffness (on the conformance suite's
squeezes Bullet reads about 700 N per mm); ``DynamicsConfig.jam_depth`` reads a jam.

Frames and units: W, metres, seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Role
from pydrake.multibody.tree import JacobianWrtVariable
from scipy.optimize import nnls

from drake_clutter.worlds.drake_world import World, drake_pair_friction

CONE_EDGES = 8  # generators of each friction cone's inscribed pyramid (ours)
CONE_TOLERANCE = 1e-3  # residual below which a direction counts as held by the cones (ours)
MAX_CHAIN = 4  # boxes followed along a chain of pushes (ours)
MIN_FORCE = 1e-3  # N: a pair carrying less is within the hydroelastic margin, not touching (ours)


@dataclass(frozen=True)
class Contact:
    """One contact between nodes ``a`` and ``b`` (None: the shelf or another static body;
    ``actor`` for the arm or pusher; box index otherwise): the unit ``normal`` pointing from
    b into a, the ``point`` in W, the pair's Coulomb coefficient ``mu`` and the geometry id
    of b (``geometry_b``: the actor's part, for its point's velocity)."""

    a: object
    b: object
    normal: np.ndarray
    point: np.ndarray
    mu: float
    geometry_b: object


ACTOR = "actor"


def _mean_normal(surface) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted normal (out of N, into M) and centroid of a hydroelastic surface."""
    mesh = surface.tri_mesh_W() if surface.is_triangle() else surface.poly_mesh_W()
    normal = np.zeros(3)
    for f in range(mesh.num_faces()):
        normal += mesh.area(f) * mesh.face_normal(f)
    return normal / max(np.linalg.norm(normal), 1e-12), np.asarray(surface.centroid())


class JamReader:
    """Reads the blocked boxes and the commanded approach into them from a Drake world's
    current contact results. ``nodes`` maps collision geometry ids to ``ACTOR`` or a box index;
    geometries absent from it (the shelf, frozen boxes) are static."""

    def __init__(self, world: World, nodes: dict):
        self.world, self.nodes = world, nodes
        self._inspector = world.scene_graph.model_inspector()
        self._mu: dict = {}

    def _friction(self, id_a, id_b) -> float:
        """Drake's pair coefficient of two geometries' static friction."""
        key = (id_a, id_b) if id_a < id_b else (id_b, id_a)
        if key not in self._mu:
            mus = [self._inspector.GetProperties(g, Role.kProximity).GetProperty(
                "material", "coulomb_friction").static_friction() for g in key]
            self._mu[key] = drake_pair_friction(*mus)
        return self._mu[key]

    def contacts(self, context) -> list[Contact]:
        """Every contact of the current step that carries a force (MIN_FORCE), both ways
        round (each contact appears as (a, b) and (b, a))."""
        results = self.world.plant.get_contact_results_output_port().Eval(context)
        raw = []
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)
            if np.linalg.norm(info.contact_force()) < MIN_FORCE:
                continue
            pair = info.point_pair()
            point = (np.asarray(pair.p_WCa) + np.asarray(pair.p_WCb)) / 2
            raw.append((pair.id_A, pair.id_B, np.asarray(pair.nhat_BA_W), point))
        for i in range(results.num_hydroelastic_contacts()):
            info = results.hydroelastic_contact_info(i)
            if np.linalg.norm(info.F_Ac_W().translational()) < MIN_FORCE:
                continue
            surface = info.contact_surface()
            normal, point = _mean_normal(surface)
            raw.append((surface.id_M(), surface.id_N(), normal, point))
        out = []
        for id_a, id_b, normal, point in raw:
            a, b = self.nodes.get(id_a), self.nodes.get(id_b)
            if a == b:
                continue
            mu = self._friction(id_a, id_b)
            out.append(Contact(a, b, normal, point, mu, id_b))
            out.append(Contact(b, a, -normal, point, mu, id_a))
        return out

    def approach(self, context, v_commanded: np.ndarray) -> dict:
        """box index -> the actor's commanded approach speed into it while it is blocked
        (m/s, `approach_speeds`: the largest over the actor's contacts with it, > 0).
        ``v_commanded`` is the plant's generalized velocity with the actor's commanded joint
        velocities (zero elsewhere)."""
        return approach_speeds(self.contacts(context), lambda c: self._point_velocity(
            context, c.geometry_b, c.point, v_commanded))

    def _point_velocity(self, context, geometry, point: np.ndarray,
                        v_commanded: np.ndarray) -> np.ndarray:
        """Velocity in W (m/s) of the material point at ``point`` (W) of the body carrying
        ``geometry``, under the generalized velocity ``v_commanded``."""
        plant = self.world.plant
        body = plant.GetBodyFromFrameId(self._inspector.GetFrameId(geometry))
        X_WB = plant.EvalBodyPoseInWorld(context, body)
        J = plant.CalcJacobianTranslationalVelocity(
            context, JacobianWrtVariable.kV, body.body_frame(), X_WB.inverse() @ point,
            plant.world_frame(), plant.world_frame())
        return J @ v_commanded


def approach_speeds(contacts: list[Contact], point_velocity) -> dict:
    """box index -> the actor's commanded approach speed into it while it is blocked (m/s,
    the largest over the actor's contacts with it, > 0; boxes not blocked or not approached
    are absent), from a step's ``contacts`` (both ways round) and ``point_velocity(contact)``:
    the W velocity of the actor's material point at ``contact.point`` under the commanded
    joint velocities. A contact's speed is read first and `blocked` asked only where it
    would raise the box's answer (the blocked test is the costly part)."""
    out: dict = {}
    cones, index = {}, None
    for c in contacts:
        if c.b != ACTOR or c.a in (None, ACTOR):
            continue
        push = c.normal  # from the actor into the box
        speed = float(point_velocity(c) @ push)
        if speed <= out.get(c.a, 0.0):
            continue
        if index is None:
            index = _Index(contacts)
        if blocked(c.a, push, contacts, (c.a,), cones, index):
            out[c.a] = speed
    return out


class _Index:
    """A step's contacts by their node ``a`` and the answers of `blocked` found so far (a
    box's several contact points with one face share their normal: the same question)."""

    def __init__(self, contacts: list[Contact]):
        self.by_node: dict = {}
        for c in contacts:
            self.by_node.setdefault(c.a, []).append(c)
        self.answers: dict = {}


_ANGLES = 2 * np.pi * np.arange(CONE_EDGES) / CONE_EDGES
_COS, _SIN = np.cos(_ANGLES)[:, None], np.sin(_ANGLES)[:, None]


def cone_generators(normals: np.ndarray, mus: np.ndarray) -> np.ndarray:
    """(n, CONE_EDGES, 3) unit generators of the pyramids inscribed in the friction cones
    about the unit ``normals`` (n, 3) with coefficients ``mus`` (n,), each edge at atan(mu)
    from its normal, the edges evenly spread about it."""
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    helper = np.eye(3)[np.argmin(np.abs(normals), axis=1)]
    t1 = _cross_rows(normals, helper)
    t1 /= np.sqrt((t1 * t1).sum(axis=1, keepdims=True))
    t2 = _cross_rows(normals, t1)
    mu = np.asarray(mus, dtype=float).reshape(-1, 1, 1)
    edges = normals[:, None, :] + mu * (_COS[None] * t1[:, None, :] + _SIN[None] * t2[:, None, :])
    return edges / np.sqrt((edges * edges).sum(axis=2, keepdims=True))


def _cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a x b of (n, 3) arrays (np.cross's arithmetic, without its overhead)."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def held(direction: np.ndarray, generators: list[np.ndarray]) -> bool:
    """Whether the reactions ``generators`` (unit rows) can balance a push along
    ``direction``: -direction lies in their cone (non-negative least squares)."""
    if not generators:
        return False
    G = np.array(generators).T  # rows (3,): np.vstack's checks cost more here
    _, residual = nnls(G, -np.asarray(direction, dtype=float))
    return residual < CONE_TOLERANCE


def blocked(box, push: np.ndarray, contacts: list[Contact], chain: tuple = (),
            cones: dict | None = None, index: _Index | None = None) -> bool:
    """Whether ``box``, pushed along the unit ``push``, cannot move in a rigid world: its
    static contacts' friction cones, and those of boxes it presses that are blocked in turn
    (followed up to MAX_CHAIN boxes, never back along ``chain``), hold the push. ``cones``:
    each contact's cone generators by id, filled as they are met (the chains meet the same
    contacts many times); ``index``: the contacts by node and the answers so far (built here
    if None). The cones only add reactions, so the answer is yes as soon as some of them hold
    the push; the boxes further along are then not asked."""
    cones = {} if cones is None else cones
    index = _Index(contacts) if index is None else index
    key = (box, np.asarray(push, dtype=float).tobytes(), chain)
    if key in index.answers:
        return index.answers[key]
    reactions, pressed = [], []
    for c in index.by_node.get(box, ()):
        if c.b == ACTOR:
            continue
        if c.b is None:
            reactions.append(c)
        elif c.b not in chain and len(chain) < MAX_CHAIN and float(c.normal @ push) < 0.0:
            pressed.append(c)
    answer = _held_by(push, reactions, cones)
    for c in pressed:
        if answer:
            break
        if blocked(c.b, -c.normal, contacts, chain + (c.b,), cones, index):
            reactions.append(c)
            answer = _held_by(push, reactions, cones)
    index.answers[key] = answer
    return answer


def _held_by(push: np.ndarray, reactions: list[Contact], cones: dict) -> bool:
    """`held` of a push along ``push`` by the friction cones of the ``reactions``: answered
    from their normals alone where `proved_free` proves it is not held, their generators
    (from ``cones`` by id, the missing ones computed in bulk and kept there) read otherwise."""
    if not reactions:
        return False
    if proved_free(-np.asarray(push, dtype=float), [c.normal for c in reactions],
                   [c.mu for c in reactions]):
        return False
    missing = [c for c in reactions if id(c) not in cones]
    if missing:
        generators = cone_generators(np.array([c.normal for c in missing]),
                                     np.array([c.mu for c in missing]))
        cones.update({id(c): g for c, g in zip(missing, generators, strict=True)})
    return held(push, [g for c in reactions for g in cones[id(c)]])


def proved_free(direction, normals, mus) -> bool:
    """Whether the unit ``direction`` (a push's opposite) is proved outside the friction
    cones about the unit ``normals`` (3-sequences) with coefficients ``mus``, so that `held`
    says no: `outside_cone_hull` first (plain floats), then `outside_cones`, each with twice
    `held`'s tolerance as margin. A no proves nothing."""
    margin = 2 * CONE_TOLERANCE
    return outside_cone_hull(direction, normals, mus, margin) or outside_cones(
        np.asarray(direction, dtype=float), np.asarray(normals, dtype=float).reshape(-1, 3),
        np.asarray(mus, dtype=float), margin)


def outside_cone_hull(direction, normals, mus, margin: float) -> bool:
    """`outside_cones` in plain floats for a few contacts (no array built): the cones about
    the unit ``normals`` (3-sequences) all lie in one cone about their mean direction n, of
    half-angle b = max(angle(n_i, n) + atan(mu_i)); where b < 90 deg and the unit
    ``direction`` is more than asin(``margin``) beyond it, it is farther than ``margin`` from
    every combination of them. Where this says no, `outside_cones` may still say yes."""
    mx, my, mz = (sum(n[k] for n in normals) for k in range(3))
    size = math.sqrt(mx * mx + my * my + mz * mz)
    if size < 1e-9:
        return False
    mx, my, mz = mx / size, my / size, mz / size
    half = max(math.acos(min(1.0, max(-1.0, n[0] * mx + n[1] * my + n[2] * mz)))
               + math.atan(mu) for n, mu in zip(normals, mus, strict=True))
    if half >= math.pi / 2:
        return False
    d = direction
    angle = math.acos(min(1.0, max(-1.0, d[0] * mx + d[1] * my + d[2] * mz)))
    return angle - half >= math.asin(margin)


_TILTS = np.array([0.05, 0.15, 0.4, 1.0, 2.5, 6.0])  # trial tilts of `outside_cones`' planes


def outside_cones(direction: np.ndarray, normals: np.ndarray, mus: np.ndarray,
                  margin: float) -> bool:
    """Whether the unit ``direction`` is farther than ``margin`` from every non-negative
    combination of the friction cones about the unit ``normals`` (n, 3) with coefficients
    ``mus`` (n,), proved by a plane through the origin: w = n - t d (n the normals' mean
    direction, d the direction, t a few trial tilts) with every cone on its side (n_i . w >=
    sin(atan(mu_i)) |w|) and the direction more than ``margin`` beyond it. The pyramids
    `held` reads are inscribed in these cones, so where this says yes, `held` says no (its
    residual is at least the distance to the plane); a no proves nothing."""
    mean = normals.sum(axis=0)
    size = float(np.sqrt(mean @ mean))
    if size < 1e-9:
        return False
    planes = mean / size - _TILTS[:, None] * direction
    planes /= np.sqrt((planes * planes).sum(axis=1, keepdims=True))
    sines = mus / np.sqrt(1.0 + mus * mus)
    sides = (normals @ planes.T >= sines[:, None]).all(axis=0)
    return bool(np.any(sides & (planes @ direction <= -margin)))
