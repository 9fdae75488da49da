"""pybullet's collision filter, mirrored: which pairs of frames pybullet lets collide.

pybullet decides in its broadphase filter callback (PhysicsServerCommandProcessor's
MyOverlapFilterCallback and the collision filter plugin), for two collision objects
(a multibody link, or a maximal-coordinate body as link -1):

1. a pair rule set by ``setCollisionFilterPair`` for exactly those two (body, link)
   decides (rules are keyed by body id: they outlive a removed body and apply to a new
   body that reuses its id; ``resetSimulation`` clears them);
2. otherwise the group/mask test of ``collisionFilterMode``: group A & mask B, and (mode
   0) or (mode 1, pybullet's default) group B & mask A, non-zero.

A link's group and mask are pybullet's defaults for its kind (a fixed base: the static
group 2 with mask ~2; every other link and free base: group 1, mask -1), then a URDF's
``<collision group= mask=>``, then ``setCollisionFilterGroupMask``. ``changeDynamics``
that switches a base between fixed and free resets it to the new kind's defaults.
The rules, groups and masks are those the journal (``_hooks``) saw being set.
"""

from __future__ import annotations

import numpy as np

from ._hooks import OR_MODE, pair_rule_key

__all__ = ["default_group_mask", "Filters"]

_STATIC_FILTER, _DEFAULT_FILTER, _ALL = 2, 1, -1


def default_group_mask(fixed: bool) -> tuple[int, int]:
    """pybullet's group and mask of a collision object: a fixed base's, or any other's."""
    return (_STATIC_FILTER, _ALL ^ _STATIC_FILTER) if fixed else (_DEFAULT_FILTER, _ALL)


class Filters:
    """Group, mask and pair rules of the tracked frames, and the decision for a pair."""

    def __init__(self, keys, defaults, file_group_mask, journal, others=None):
        """``keys``: (body, link) per frame; ``defaults``: (group, mask) per frame before the
        user's settings; ``file_group_mask``: {(body, link): (group or None, mask or None)};
        ``others``: {(body, link): (defaults, the file's (group, mask) or None)} of shapes no
        frame carries (``allowed_shape``)."""
        group, mask = zip(*(_group_mask(journal, key, d, file_group_mask.get(key))
                            for key, d in zip(keys, defaults))) if keys else ((), ())
        self.others = {key: _group_mask(journal, key, d, fgm) for key, (d, fgm) in (others or {}).items()}
        self.group = np.array(group, dtype=np.int64)
        self.mask = np.array(mask, dtype=np.int64)
        self.mode = journal.filter_mode
        self.rules = journal.pair_rules
        self.keys = keys

    def allowed(self, fa: int, fb: int) -> bool:
        """Whether pybullet lets frames fa and fb collide."""
        return self._decide(fa, self.keys[fb], self.group[fb], self.mask[fb])

    def allowed_shape(self, fa: int, key) -> bool:
        """Whether pybullet lets frame fa collide with the shape of (body, link) ``key`` in
        ``others``."""
        return self._decide(fa, key, *self.others[key])

    def _decide(self, fa, key, group, mask) -> bool:
        """Frame fa against the collision object ``key`` of that group and mask: its pair
        rule, else the group/mask test of the filter mode."""
        rule = self.rules.get(pair_rule_key(*self.keys[fa], *key)) if self.rules else None
        if rule is not None:
            return rule
        ab = (self.group[fa] & mask) != 0
        ba = (group & self.mask[fa]) != 0
        return bool(ab or ba) if self.mode == OR_MODE else bool(ab and ba)

    def allowed_pairs(self, fa: np.ndarray, fb: np.ndarray) -> np.ndarray:
        """(n,) bool: ``allowed`` for n pairs of frame indices."""
        ab = (self.group[fa] & self.mask[fb]) != 0
        ba = (self.group[fb] & self.mask[fa]) != 0
        ok = (ab | ba) if self.mode == OR_MODE else (ab & ba)
        if self.rules:
            for k, (a, b) in enumerate(zip(fa.tolist(), fb.tolist())):
                rule = self.rules.get(pair_rule_key(*self.keys[a], *self.keys[b]))
                if rule is not None:
                    ok[k] = rule
        return ok


def _group_mask(journal, key, default, file_group_mask):
    """A collision object's (group, mask): the user's, else its file's (each of the two where
    the file sets it), else pybullet's default."""
    fg, fm = file_group_mask or (None, None)
    return journal.group_mask.get(key, (default[0] if fg is None else fg, default[1] if fm is None else fm))
