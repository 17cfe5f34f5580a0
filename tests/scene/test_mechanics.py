"""The quasi-static tipping rule of a pushed box, alone and shoving boxes ahead."""

from __future__ import annotations

import pytest

from drake_clutter.scene.mechanics import G, chain_tip_ratio, tip_ratio


def test_a_lone_box_tips_where_the_push_moment_beats_the_weight():
    # 10 cm long, mu_b 0.5, mu_p 0.4: the threshold height is (w/2)(1 + 0.2) / 0.5 = 12 cm
    assert tip_ratio(0.1, 0.12, 0.5, 0.4) == pytest.approx(1.0)
    assert tip_ratio(0.1, 0.06, 0.5, 0.4) == pytest.approx(0.5)
    assert chain_tip_ratio(0.1, 0.06, 0.5, 0.4, mass=0.3) == pytest.approx(0.5)


def test_a_load_ahead_tips_the_box_sooner_unless_it_presses_at_the_push_height():
    lone = chain_tip_ratio(0.08, 0.05, 0.6, 0.6, mass=0.2)
    low = chain_tip_ratio(0.08, 0.05, 0.6, 0.6, mass=0.2, load=1.0, load_z=0.02)
    level = chain_tip_ratio(0.08, 0.05, 0.6, 0.6, mass=0.2, load=1.0, load_z=0.05)
    assert low > lone and level == pytest.approx(lone)
    # the moment balance by hand: (mu m g + L) z - L z_L over (w/2)(1 + mu mu_p) m g
    by_hand = ((0.6 * 0.2 * G + 1.0) * 0.05 - 1.0 * 0.02) / (0.04 * 1.36 * 0.2 * G)
    assert low == pytest.approx(by_hand)
