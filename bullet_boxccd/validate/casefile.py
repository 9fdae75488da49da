"""Replayable case files: one box pair and the answer under test, every number to 20 digits.

A case file is the JSON that ``boxccd toi FILE`` reads (``lo_a``, ``hi_a``, ``coeffs_a``,
``lo_b``, ``hi_b``, ``coeffs_b``, ``t_range``), plus what the validation found:
``solver_t`` (the answer judged, null for none), ``verdict``, ``evidence_t`` (the time of
the certified overlap, for a miss or a late answer), the family, its knob, and where the
query came from (seed, shard, index in its family's batch). 20 significant digits read
back to the same doubles (17 would do; 20 is the house format for repros).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["case_text", "read_case", "case_name"]

_GEOMETRY = ("lo_a", "hi_a", "coeffs_a", "lo_b", "hi_b", "coeffs_b")


def _num(x) -> str:
    x = float(x)
    return "null" if not np.isfinite(x) else format(x, ".20g")


def _nested(a, indent=4) -> str:
    """Nested lists, one innermost row per line (a motion reads as three 4 x 4 blocks)."""
    a = np.asarray(a, dtype=float)
    if a.ndim == 0:
        return _num(a)
    if a.ndim == 1:
        return "[" + ", ".join(_num(x) for x in a) + "]"
    pad = "\n" + " " * (indent + 1)
    return "[" + ("," + pad).join(_nested(x, indent + 1) for x in a) + "]"


def case_name(family: str, seed: int, shard: int, index: int, verdict: str) -> str:
    return f"{family}_s{seed}_k{shard}_i{index}_{verdict}.json"


def case_text(batch, i: int, solver_t: float, verdict: str, evidence_t: float, origin: dict) -> str:
    """The JSON text of query ``i`` of ``batch`` (a ``QueryBatch``)."""
    fields = {k: _nested(getattr(batch, k)[i]) for k in _GEOMETRY}
    fields["t_range"] = _nested(batch.t_range)
    fields["solver_t"] = _num(solver_t)
    fields["verdict"] = json.dumps(verdict)
    fields["evidence_t"] = _num(evidence_t)
    fields["param_name"] = json.dumps(batch.param_name)
    fields["param"] = _num(batch.param[i])
    fields.update({k: json.dumps(v) for k, v in origin.items()})
    return "{\n" + ",\n".join(f'  "{k}": {v}' for k, v in fields.items()) + "\n}\n"


def read_case(path) -> dict:
    """A case file's fields, geometry as float64 arrays."""
    case = json.loads(Path(path).read_text())
    for k in _GEOMETRY:
        case[k] = np.asarray(case[k], dtype=float)
    case["t_range"] = tuple(float(x) for x in case.get("t_range", (0.0, 1.0)))
    return case
