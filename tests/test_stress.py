"""Stability at the extremes (tests/stress.py has the families). The default run
takes a reduced tier (3 cases per parameter); ``pytest -m stress`` the full sweep."""

from __future__ import annotations

import pytest
import stress

# Largest mpmath gap at a reported contact, in box sizes: the touching tolerance
# (1e-12 of the scene's size) plus the rounding allowance, which grows with the
# magnitude of the motion (speed in box lengths per range) and, for edges a
# small angle apart, as rounding / angle until the sliver of their facet caps it
# (measured worst: 1.5e-9 near 1e-4 rad; see docs/accuracy.md).
GAP_BOUND = {"speed": 1e-12 * 1e4 * 2, "near_parallel_edges": 5e-9}
DEFAULT_GAP_BOUND = 1e-9


def check_family(name, n, need_hits=True):
    results = stress.run_family(name, n)
    # Every family has contacts to get right (a solver that never reports one fails).
    assert sum(t.hits for t in results.values()) > 0, f"{name}: no case hits"
    for param, t in results.items():
        where = f"{name} {param}: " + "\n".join(t.notes[:2])
        assert t.misses == 0, "missed contacts: " + where
        assert t.false_hits == 0, "false hits: " + where
        assert t.late == 0, "late contacts: " + where
        assert t.worst_gap <= GAP_BOUND.get(name, DEFAULT_GAP_BOUND), f"early by {t.worst_gap:.3e}: " + where
        # Every family hits somewhere, except the passes that never touch by construction.
        assert t.hits > 0 or not need_hits or param in ("gap 1e-09", "gap +1e-12"), where


def check_far(n):
    """Far from the origin (turned, moved up to 1e6 box sizes): as exact as at the
    origin, and within 1e-9 of the range of the same case's answer there."""
    results = stress.far_family(n)
    assert sum(t.hits for t in results.values()) > 0, "no case hits"
    for offset, t in results.items():
        where = f"{offset}: " + "\n".join(t.notes[:2])
        assert t.misses == 0 and t.false_hits == 0 and t.late == 0, where
        assert t.worst_gap <= DEFAULT_GAP_BOUND, f"early by {t.worst_gap:.3e}: " + where
        assert t.worst_shift <= 1e-9, f"{t.worst_shift:.3e} from the answer at the origin: " + where


@pytest.mark.parametrize("name", sorted(stress.FAMILIES))
def test_extremes_reduced(name):
    check_family(name, 3, need_hits=False)


def test_far_from_the_origin_reduced():
    check_far(4)


@pytest.mark.stress
@pytest.mark.parametrize("name", sorted(stress.FAMILIES))
def test_extremes_full(name):
    check_family(name, 40)


@pytest.mark.stress
def test_far_from_the_origin_full():
    check_far(40)
