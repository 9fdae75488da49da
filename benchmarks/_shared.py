"""What the solver benchmarks share (benchmarks/solver.py, benchmarks/solver_tradeoff.py):
the seeded pair families, the dense separating-axis reference, python-fcl's
continuous collision on the same pairs, interleaved timing, and the report helpers.
Rotations, quaternions and quadratic fits come from the package (bullet_boxccd.motion),
the boxes' world vertices and their separating-axis gap from its independent oracle
(bullet_boxccd.testing).

Importing this module sets OPENBLAS_NUM_THREADS=1 before numpy loads (if unset):
OpenBLAS's worker threads spin after each call and would take the second core
from the timed code on a 2-core machine.
"""

from __future__ import annotations

import hashlib
import math
import os
import platform
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from bullet_boxccd import Box, QuadraticMotion, _core  # noqa: E402
from bullet_boxccd.motion import quat_to_matrix, rotations, screw_coeffs  # noqa: E402
from bullet_boxccd.testing import SIGNS, motion_at, placed_vertices, sat_gap, world_vertices  # noqa: E402

try:
    import fcl
except ImportError:  # the benchmarks still run, without the baseline
    fcl = None

try:
    from tqdm import tqdm as _tqdm

    def tqdm(it, **kw):
        return _tqdm(it, disable=not sys.stderr.isatty(), **kw)

except ImportError:

    def tqdm(it, **kw):
        return it


FAMILIES = ("trans", "rot", "both")


# ------------------------------------------------------------------- pairs
def random_rotations(rng, n):
    """(n, 3, 3) rotations, uniform over SO(3) (quaternions (w, x, y, z) from a normal sample)."""
    q = rng.normal(size=(n, 4))
    return quat_to_matrix(q[:, [1, 2, 3, 0]])  # pybullet's order: (x, y, z, w)


def unit_vectors(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def make_pairs(seed: int, family: int, n: int) -> dict:
    """n seeded pairs of a family (index into FAMILIES): box half extents uniform in
    [0.05, 1]; B starts 2..6 r from A (r = sum of the half diagonals, so no pair
    starts in contact) and heads for an aim point within 0.8 r of A's centre,
    reaching it at t = 1 / U(0.3, 1.5), so about half the pairs hit. ``trans``: A
    static, B translating; ``rot``: B also spins up to 0.95 pi over t in [0, 1];
    ``both``: both move (half the relative velocity each) and spin. Motions:
    bullet_boxccd.motion.screw_coeffs (exact translation, the rotation fitted
    through t = 0, 1/2, 1). Returns the boxes, the rigid motions (R0, p0, v, w) and
    their quadratic coefficients."""
    rng = np.random.default_rng([seed, family])
    name = FAMILIES[family]
    ha = rng.uniform(0.05, 1.0, size=(n, 3))
    hb = rng.uniform(0.05, 1.0, size=(n, 3))
    r = np.linalg.norm(ha, axis=1) + np.linalg.norm(hb, axis=1)
    start = unit_vectors(rng, n) * (rng.uniform(2.0, 6.0, size=n) * r)[:, None]
    aim = unit_vectors(rng, n) * (rng.uniform(0.0, 1.0, size=n) ** (1 / 3) * 0.8 * r)[:, None]
    vb = (aim - start) * rng.uniform(0.3, 1.5, size=n)[:, None]
    Ra0 = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    pa0, va, wa = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    Rb0, wb = random_rotations(rng, n), np.zeros((n, 3))
    if name in ("rot", "both"):
        wb = unit_vectors(rng, n) * rng.uniform(0.0, 0.95 * math.pi, size=n)[:, None]
    if name == "both":
        Ra0 = random_rotations(rng, n)
        va, vb = -0.5 * vb, 0.5 * vb
        wa = unit_vectors(rng, n) * rng.uniform(0.0, 0.95 * math.pi, size=n)[:, None]
    return dict(family=name, ha=ha, hb=hb, r=r, rigid_a=(Ra0, pa0, va, wa), rigid_b=(Rb0, start, vb, wb),
                ca=screw_coeffs(Ra0, pa0, va, wa), cb=screw_coeffs(Rb0, start, vb, wb))


def subset(p: dict, idx) -> dict:
    out = {}
    for k, v in p.items():
        if isinstance(v, np.ndarray):
            out[k] = v[idx]
        elif isinstance(v, tuple):
            out[k] = tuple(x[idx] for x in v)
        else:
            out[k] = v
    return out


def batch_args(p: dict):
    return (-p["ha"], p["ha"], p["ca"], -p["hb"], p["hb"], p["cb"])


def our_objects(p: dict):
    """(Box, QuadraticMotion, Box, QuadraticMotion) per pair, for time_of_impact."""
    return [(Box.centered(p["ha"][i]), QuadraticMotion(p["ca"][i]), Box.centered(p["hb"][i]),
             QuadraticMotion(p["cb"][i])) for i in range(len(p["ha"]))]


# ---------------------------------------------------- dense reference (SAT)
def rigid_pose(R0, p0, v, w, t):
    """(n, ..., 3, 4) poses at times t (scalar, (n,) or (n, T)) of the n rigid motions:
    origin p0 + v t, orientation rot(w t) R0."""
    t = np.asarray(t, dtype=float)
    t = np.broadcast_to(t, (len(R0),) + t.shape[1:])
    at = (slice(None),) + (None,) * (t.ndim - 1)  # each motion's parameters against its times
    P = np.empty(t.shape + (3, 4))
    P[..., :3] = rotations(w[at] * t[..., None]) @ R0[at]
    P[..., 3] = p0[at] + v[at] * t[..., None]
    return P


def _vertices(M, h):
    """(n, ..., 8, 3) world vertices of centred boxes (half extents h (n, 3)) placed by
    (n, ..., 3, 4) or (n, ..., 4, 4) matrices (bullet_boxccd.testing's)."""
    at = (slice(None),) + (None,) * (M.ndim - 3)
    return placed_vertices(M, -h[at], h[at])


def gap_at(p: dict, t: np.ndarray) -> np.ndarray:
    """SAT gap of each pair at its own time t (n,) under the quadratic motion."""
    return sat_gap(world_vertices(p["ca"], -p["ha"], p["ha"], t), world_vertices(p["cb"], -p["hb"], p["hb"], t))


def reference(p: dict, samples: int, rigid: bool = False, chunk: int = 8, desc: str = "reference"):
    """Dense-sampling classification of each pair (independent of both solvers): the
    separating-axis gap (bullet_boxccd.testing.sat_gap) at ``samples`` times in
    [0, 1] on the quadratic motion (or, with ``rigid``, on the rigid motion FCL
    follows). 'hit' if a sample intersects, 'miss' if the smallest gap exceeds
    max(1e-3 r, v_max dt / 2) (nothing can touch between samples), else 'ambig'.
    Returns status (n,), the first intersecting sample time (NaN if none), the
    smallest gap and the margin."""
    n = len(p["ha"])
    ts = np.linspace(0.0, 1.0, samples)
    first, mingap = np.full(n, np.nan), np.empty(n)
    for s in tqdm(range(0, n, chunk), desc=desc, leave=False, mininterval=1.0):
        q = subset(p, slice(s, min(n, s + chunk)))
        T = np.broadcast_to(ts, (len(q["ha"]), samples))
        if rigid:
            Ma, Mb = rigid_pose(*q["rigid_a"], T), rigid_pose(*q["rigid_b"], T)
        else:
            Ma, Mb = motion_at(q["ca"][:, None], T), motion_at(q["cb"][:, None], T)
        g = sat_gap(_vertices(Ma, q["ha"]), _vertices(Mb, q["hb"]))
        mingap[s:s + len(g)] = g.min(1)
        hit = g <= 0.0
        first[s:s + len(g)] = np.where(hit.any(1), ts[np.argmax(hit, axis=1)], np.nan)
    vmax = _speed_bound(p, rigid)
    margin = np.maximum(1e-3 * p["r"], vmax * (ts[1] - ts[0]) / 2.0)
    status = np.where(~np.isnan(first), "hit", np.where(mingap > margin, "miss", "ambig"))
    return dict(status=status, first=first, mingap=mingap, margin=margin)


def _speed_bound(p, rigid):
    """Upper bound of the relative vertex speed over t in [0, 1]."""
    total = 0.0
    for c, h, rg in ((p["ca"], p["ha"], p["rigid_a"]), (p["cb"], p["hb"], p["rigid_b"])):
        if rigid:
            total = total + np.linalg.norm(rg[2], axis=1) + np.linalg.norm(rg[3], axis=1) * np.linalg.norm(h, axis=1)
            continue
        x = np.concatenate([SIGNS[None] * h[:, None, :], np.ones((len(h), 8, 1))], axis=-1)
        d1 = np.linalg.norm(np.einsum("nij,nkj->nki", c[:, 1, :3], x), axis=-1)
        d2 = np.linalg.norm(np.einsum("nij,nkj->nki", c[:, 2, :3], x), axis=-1)
        total = total + (d1 + 2.0 * d2).max(-1)
    return total


# ------------------------------------------------------------------- FCL
FCL_MOTIONS = {"trans": "CCDM_TRANS", "screw": "CCDM_SCREW"}


def fcl_request(motion: str, toc_err=1e-6, iterations=100, gjk="libccd"):
    return fcl.ContinuousCollisionRequest(
        num_max_iterations=iterations, toc_err=toc_err,
        ccd_motion_type=getattr(fcl.CCDMotionType, FCL_MOTIONS[motion]),
        gjk_solver_type={"libccd": fcl.GJKSolverType.GST_LIBCCD, "indep": fcl.GJKSolverType.GST_INDEP}[gjk],
        ccd_solver_type=fcl.CCDSolverType.CCDC_CONSERVATIVE_ADVANCEMENT)


def fcl_setup(p: dict, motion: str, gjk: str = "libccd"):
    """Per pair (o1, tf1_end, o2, tf2_end, request) for fcl.continuousCollide: the same
    boxes between the same rigid start and end poses."""
    request = fcl_request(motion, gjk=gjk)
    A0, A1 = rigid_pose(*p["rigid_a"], 0.0), rigid_pose(*p["rigid_a"], 1.0)
    B0, B1 = rigid_pose(*p["rigid_b"], 0.0), rigid_pose(*p["rigid_b"], 1.0)
    return [(fcl.CollisionObject(fcl.Box(*(2.0 * p["ha"][i])), fcl.Transform(A0[i, :, :3], A0[i, :, 3])),
             fcl.Transform(A1[i, :, :3], A1[i, :, 3]),
             fcl.CollisionObject(fcl.Box(*(2.0 * p["hb"][i])), fcl.Transform(B0[i, :, :3], B0[i, :, 3])),
             fcl.Transform(B1[i, :, :3], B1[i, :, 3]), request) for i in range(len(p["ha"]))]


def fcl_query(o1, tf1, o2, tf2, request):
    result = fcl.ContinuousCollisionResult()
    fcl.continuousCollide(o1, tf1, o2, tf2, request, result)
    return result


def fcl_safe(o1, tf1, o2, tf2, request):
    try:
        return fcl_query(o1, tf1, o2, tf2, request)
    except Exception:
        return None


def fcl_answers(items):
    """(n,) contact time (NaN: no hit) and (n,) bool: FCL raised."""
    t, err = np.full(len(items), np.nan), np.zeros(len(items), dtype=bool)
    for i, it in enumerate(items):
        try:
            r = fcl_query(*it)
            if r.is_collide:
                t[i] = r.time_of_contact
        except Exception:
            err[i] = True
    return t, err


# ----------------------------------------------------------------- timing
def round_robin(jobs: dict, rounds: int, desc: str = "timing"):
    """jobs: name -> zero-argument callable that runs one pass and returns how many
    queries it made. Each round runs every job once, in an order rotated from round
    to round, so that drifts of a shared machine hit every job alike. Returns name
    -> (n_rounds,) seconds per query."""
    for job in jobs.values():
        job()  # warm-up
    names = list(jobs)
    out = {k: [] for k in names}
    clock = time.perf_counter
    for r in tqdm(range(rounds), desc=desc, leave=False):
        for k in names[r % len(names):] + names[:r % len(names)]:
            t0 = clock()
            n = jobs[k]()
            out[k].append((clock() - t0) / n)
    return {k: np.array(v) for k, v in out.items()}


# ---------------------------------------------------------------- reports
def machine_info() -> list[str]:
    cpu = platform.processor() or "?"
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), cpu)
    except OSError:
        pass
    fcl_version = getattr(fcl, "__version__", "?") if fcl is not None else "not installed"
    with open(_core.__file__, "rb") as f:
        core_sha = hashlib.sha256(f.read()).hexdigest()[:12]
    core_time = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(os.path.getmtime(_core.__file__)))
    return [f"platform: {platform.platform()}", f"cpu: {cpu} ({os.cpu_count()} logical cpus)",
            f"python {platform.python_version()}, numpy {np.__version__}, python-fcl {fcl_version}, "
            f"bullet_boxccd core {os.path.basename(_core.__file__)} (sha256 {core_sha}, built {core_time})"]


def g20(x) -> str:
    return f"{float(x):.20g}"


def repro(p: dict, i: int) -> str:
    """Pair i of a family, to 20 digits, as Python code."""
    def L(a):
        return "[" + ", ".join(L(x) if isinstance(x, np.ndarray) else g20(x) for x in a) + "]"

    return (f"a = Box.centered({L(p['ha'][i])}); b = Box.centered({L(p['hb'][i])}); "
            f"ma = QuadraticMotion(np.array({L(p['ca'][i])})); mb = QuadraticMotion(np.array({L(p['cb'][i])}))")
