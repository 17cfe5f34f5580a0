"""Quasi-static mechanics of a box pushed on the board: does the push slide it or tip it?

A box of mass m, its length w along the push, rests on the board (Coulomb mu_b) and is pushed
horizontally at height z above its bottom by a pusher (Coulomb mu_p on the box's face). While
it slides, the board's friction mu_b N and any load L (N) that boxes shoved ahead of it press
back on its leading face at height z_L hold it; it tips about its leading bottom edge where the
push's moment beats the weight's (the pusher's friction adding to the weight). Frames: the
push's; metres, kilograms, newtons.
"""

from __future__ import annotations

G = 9.81  # m/s^2


def tip_ratio(length: float, push_z: float, mu_board: float, mu_pusher: float) -> float:
    """mu_b z / ((w / 2)(1 + mu_b mu_p)) of a lone box: above 1 quasi-static mechanics tips
    it."""
    return mu_board * push_z / (length / 2 * (1.0 + mu_board * mu_pusher))


def chain_tip_ratio(length: float, push_z: float, mu_board: float, mu_pusher: float,
                    mass: float, load: float = 0.0, load_z: float = 0.0) -> float:
    """`tip_ratio` of a box of ``mass`` (kg) that also shoves a load ``load`` (N, the friction
    of the boxes ahead of it) pressing back at ``load_z`` (m above its bottom): the push
    (mu_b m g + L) at z less the load's moment L z_L, over the weight's m g (w / 2) with the
    pusher's friction; the lone box's ratio where ``load`` is 0."""
    weight = mass * G
    moment = (mu_board * weight + load) * push_z - load * load_z
    return moment / (length / 2 * (1.0 + mu_board * mu_pusher) * weight)
