"""What the plugin reports: contact events, counters, and its warning category."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ..solver import Feature, Outcome

__all__ = ["BoxCCDWarning", "ClientDisconnectedError", "CCDEvent", "CCDStats"]


class BoxCCDWarning(UserWarning):
    """Something in the world BoxCCD cannot see or handle (named in the message); what
    it concerns is left to pybullet."""


class ClientDisconnectedError(RuntimeError):
    """The physics client a BoxCCD steps was disconnected (a world connected later under the
    same id is another world: make a BoxCCD for it)."""


def not_finite_message(body) -> str:
    """The warning for a body whose state pybullet left not finite."""
    return f"body {body}: its state in pybullet is not finite (NaN or infinite): pybullet steps it alone, unswept"


@dataclass(frozen=True)
class CCDEvent:
    """A contact found by sweeping a step.

    ``tau`` is the contact's fraction of the step (0 = start, 1 = end) and ``time``
    the same in seconds after the step started; ``point`` and ``normal`` (unit,
    from box A towards box B) are world coordinates at the first touch;
    ``feature`` names the BMS plane (None where the search found none: a link box
    touching at the start of the step, or on a piece too fast to fit); ``rewound`` says whether the
    contact was acted on: the world (or, with no partial step left, the pair's bodies)
    taken back to it, or a body pushed ahead of a kinematic one; False where pybullet
    resolves it from where the step left it;
    ``initial`` marks a pair that already touched when the step began and pressed
    deeper during it.
    """

    body_a: int
    link_a: int
    body_b: int
    link_b: int
    tau: float
    time: float
    point: np.ndarray
    normal: np.ndarray
    feature: Optional[Feature]
    rewound: bool
    initial: bool


@dataclass
class CCDStats:
    """Counters since construction (``tracked_boxes`` is the current count)."""

    steps: int = 0
    tracked_boxes: int = 0
    swept_boxes: int = 0
    candidate_pairs: int = 0
    solver_rows: int = 0  # solver calls: a pair whose step is split into n pieces counts up to n
    contacts: int = 0
    rewinds: int = 0  # times the world, or a body on its own, was taken back to a contact
    partial_steps: int = 0  # rest-of-step simulations from such a contact
    # stepSimulations added by taking steps in pieces while a body an impact set turning
    # pivots on a contact faster than its turn limit (``max_turn``)
    pieces: int = 0
    pushes: int = 0  # bodies moved ahead of a kinematic body that swept into them
    rediscoveries: int = 0  # world changes read
    # What the exact searches answered, by Outcome value (index with bullet_boxccd.Outcome):
    # every candidate pair's first touch and every contact refit. A degraded answer
    # (STEP_CAP, CLUSTERED_ROOTS: early, not proven a contact) is acted on like a contact,
    # which is never late, and counted here under its own name, never as a HIT;
    # NON_FINITE counts pairs with a row pybullet left not finite (left to pybullet).
    outcomes: np.ndarray = field(default_factory=lambda: np.zeros(len(Outcome), dtype=np.int64))
    # Wall time by phase: pybullet's stepSimulation, reading state, broad phase, solving,
    # rewinding. A step in a world where nothing changed since the last is not timed
    # until something in it is fast (its stepSimulation then counts for nothing here).
    seconds: dict = field(default_factory=lambda: dict.fromkeys(
        ("step", "state", "broad_phase", "solve", "rewind"), 0.0))

    @property
    def degraded(self) -> int:
        """Answers that hit a cap or a root cluster (``outcomes`` of STEP_CAP and CLUSTERED_ROOTS)."""
        return int(self.outcomes[Outcome.STEP_CAP] + self.outcomes[Outcome.CLUSTERED_ROOTS])

    def count(self, states) -> None:
        """Add the outcomes ``states`` (int8 values of Outcome) to ``outcomes``."""
        self.outcomes += np.bincount(np.asarray(states, dtype=np.int64), minlength=len(self.outcomes))
