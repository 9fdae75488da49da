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
    for param, t in stress.run_family(name, n).items():
        where = f"{name} {param}: " + "\n".join(t.notes[:2])
        assert t.misses == 0, "missed contacts: " + where
        assert t.false_hits == 0, "false hits: " + where
        assert t.late == 0, "late contacts: " + where
        assert t.worst_gap <= GAP_BOUND.get(name, DEFAULT_GAP_BOUND), f"early by {t.worst_gap:.3e}: " + where
        # Every family hits somewhere, except the passes that never touch by construction.
        assert t.hits > 0 or not need_hits or param in ("gap 1e-09", "gap +1e-12"), where


def check_far(n):
    for offset, r in stress.far_family(n).items():
        assert r["disagreements"] == 0, offset
        # |dt| x speed within 2e4 eps of the offset: the rounding allowance's bound.
        assert r["worst_units"] <= 2e4, (offset, r)


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
