"""Gating and assignment tables."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from studio.track.gnn import chi2_gate, gnn_assign, greedy_assign, mahalanobis_costs


def test_chi2_gate():
    assert chi2_gate(0.99) == pytest.approx(9.2103, abs=1e-3)
    assert chi2_gate(0.95, 3) == pytest.approx(chi2.ppf(0.95, 3))
    with pytest.raises(ValueError, match="probability"):
        chi2_gate(1.0)


def test_mahalanobis_costs_match_direct_computation():
    rng = np.random.default_rng(0)
    zp, z = rng.normal(size=(3, 2)), rng.normal(size=(4, 2))
    A, B = rng.normal(size=(3, 2, 2)), rng.normal(size=(4, 2, 2))
    Pz = A @ np.swapaxes(A, 1, 2) + 0.1 * np.eye(2)
    R = B @ np.swapaxes(B, 1, 2) + 0.1 * np.eye(2)
    d2, logdet = mahalanobis_costs(zp, Pz, z, R)
    for t in range(3):
        for n in range(4):
            S = Pz[t] + R[n]
            y = z[n] - zp[t]
            assert d2[t, n] == pytest.approx(y @ np.linalg.solve(S, y))
            assert logdet[t, n] == pytest.approx(np.log(np.linalg.det(S)))
    e1, e2 = mahalanobis_costs(zp[:0], Pz[:0], z, R)
    assert e1.shape == e2.shape == (0, 4)


# (name, track predictions, observations, expected pairs)
CASES = [
    ("two targets, in order", [[0, 0], [2, 0]], [[0.05, 0], [2.1, 0]], [(0, 0), (1, 1)]),
    ("two targets, swapped rows", [[0, 0], [2, 0]], [[2.1, 0], [0.05, 0]], [(0, 1), (1, 0)]),
    # crossing: both detections near the middle; the global optimum keeps each on its own side
    ("crossing targets", [[-0.1, 0], [0.1, 0]], [[-0.08, 0.02], [0.12, -0.02]], [(0, 0), (1, 1)]),
    ("missed detection", [[0, 0], [2, 0]], [[2.05, 0]], [(1, 0)]),
    ("clutter far away", [[0, 0], [2, 0]], [[0, 0.05], [2, 0.05], [9, 9]], [(0, 0), (1, 1)]),
    ("nothing in the gate", [[0, 0]], [[3, 3]], []),
]


@pytest.mark.parametrize(("name", "pred", "obs", "expected"), CASES, ids=[c[0] for c in CASES])
def test_gated_gnn_table(name, pred, obs, expected):
    zp, z = np.array(pred, float), np.array(obs, float)
    Pz = np.tile(np.eye(2) * 0.01, (len(zp), 1, 1))
    R = np.tile(np.eye(2) * 0.0025, (len(z), 1, 1))
    d2, logdet = mahalanobis_costs(zp, Pz, z, R)
    assert gnn_assign(d2 + logdet, d2 <= chi2_gate(0.999)) == expected


def test_gnn_is_global_where_greedy_is_not():
    # greedy takes the closest pair (0, 0) first and leaves track 1 without its only candidate
    cost = np.array([[1.0, 2.0], [1.5, 100.0]])
    allowed = np.array([[True, True], [True, False]])
    assert gnn_assign(cost, allowed) == [(0, 1), (1, 0)]
    assert greedy_assign(np.where(allowed, cost, np.inf), 10.0) == [(0, 0)]


def test_gnn_with_miss_cost_prefers_one_good_pair_to_two_poor_ones():
    cost = np.array([[0.1, 1.9], [1.9, 9.0]])
    allowed = np.array([[True, True], [True, False]])
    assert gnn_assign(cost, allowed) == [(0, 1), (1, 0)]  # most pairs first
    assert gnn_assign(cost, allowed, miss_cost=1.0) == [(0, 0)]  # 0.1 + 2 misses < 1.9 + 1.9
    assert gnn_assign(cost, allowed, miss_cost=0.01) == []  # nothing is worth pairing
    assert gnn_assign(np.zeros((0, 3)), np.zeros((0, 3), bool), miss_cost=1.0) == []


def test_greedy_assign_table():
    d = np.array([[0.1, 0.3, 0.9], [0.2, 0.6, 0.4]])
    assert greedy_assign(d, 0.5) == [(0, 0), (1, 2)]
    assert greedy_assign(d, 0.15) == [(0, 0)]
    assert greedy_assign(d, 0.05) == []
    assert greedy_assign(np.zeros((2, 0)), 1.0) == []
