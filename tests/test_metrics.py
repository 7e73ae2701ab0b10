"""Flipped limb segments (``pinrecon.metrics``) on a segment built by hand."""

from __future__ import annotations

import numpy as np

import pinrecon as pr
from pinrecon.metrics import flip_rate, flipped_segments


def test_flipped_segments_by_hand():
    """An orthographic camera looking along +z: a 1 m segment whose child lies 0.5 m
    behind its parent in every frame; the estimate puts it in front in frames 1 and 2, and
    in frame 3 the truth is edge-on (depth difference 0.05 m < 10 % of the length)."""
    cam = pr.Orthographic(np.eye(3), 100.0)
    T = 4
    G = np.zeros((T, 2, 3))
    G[:, 1] = [np.sqrt(0.75), 0.0, 0.5]
    G[3, 1] = [np.sqrt(1 - 0.05**2), 0.0, 0.05]
    P = G.copy()
    P[[1, 2], 1, 2] *= -1.0
    P[3, 1, 2] = -0.05  # flipped, but not counted
    flip, count = flipped_segments(P, G, cam, [(0, 1)])
    np.testing.assert_array_equal(count[:, 0], [True, True, True, False])
    np.testing.assert_array_equal(flip[:, 0], [False, True, True, False])
    assert flip_rate(P, G, cam, [(0, 1)]) == 2 / 3
    assert flip_rate(P, G, cam, [(0, 1)], per_segment=True)[1] == [(2, 3)]
