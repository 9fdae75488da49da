"""Benchmark of the bullet_boxccd solver against python-fcl, with an independent reference.

What it measures
----------------
On seeded random box pairs (numpy ``Generator``), for three motion families

* ``trans``: box A static at the origin, box B translating (rigid, ballistic, no spin),
* ``rot``:   box A static, box B translating and spinning (``QuadraticMotion.screw``,
  angular speed up to 0.95 pi rad over t in [0, 1]),
* ``both``:  both boxes translating (half the relative velocity each) and spinning.

Box half extents are uniform in [0.05, 1]; B starts at distance 2..6 r from A (r = sum
of the two half diagonals, so no pair starts in contact) and heads for a random aim
point within 0.8 r of A's centre, reaching it at t = 1 / U(0.3, 1.5); about half of
the pairs hit. Results are reported separately for the pairs that hit within t in
[0, 1] and those that stay apart (classified by our solver's answer):

* ``ours time_of_impact``: median latency of one ``time_of_impact`` call from Python
  (per pair: median over repeats of a timed loop; then the median over pairs),
* ``ours time_of_impact_batch``: throughput of ``time_of_impact_batch`` on one array
  of pairs (pairs/s, one core, best of 5), and with the array split over as many Python
  threads as there are cores (up to 4): the speed-up shows the core releasing the GIL,
* ``fcl CA <motion>``: python-fcl ``continuousCollide`` on the same boxes between the
  same rigid start and end poses, with its conservative-advancement solver
  (``CCDC_CONSERVATIVE_ADVANCEMENT``) and each of its motion types ``CCDM_TRANS``
  (translation only: it ignores the spin, as intended), ``CCDM_LINEAR`` (FCL's
  ``InterpMotion``: the origin moves on a line while the box spins about it at a
  constant rate, the rigid motion that ``QuadraticMotion.screw`` fits) and
  ``CCDM_SCREW`` (a true screw motion between the two end poses). Reported: the
  median latency per query, the agreement of its contact time with ours, and its
  misses, false hits and errors (exceptions) against the reference below.

Reference (independent of both solvers): the same quadratic motion M(t) our solver
gets, sampled densely (``--samples``, default 2000 times in [0, 1]); at each time a
separating-axis test on the two parallelepipeds (15 axes: 3 face normals of each and
the 9 edge cross products) gives a gap (> 0: separated, <= 0: intersecting). A pair
is a clear hit if some sample intersects, a clear miss if the smallest gap exceeds
``max(1e-3 * r, v_max * dt / 2)`` (r = sum of the two boxes' half diagonals, v_max a
bound on the relative vertex speed, so nothing can touch between samples), and
ambiguous otherwise (left out of the miss / false-hit counts, counted in ``ambig``).
For the spinning families FCL follows the rigid motion, not its quadratic fit; the
script therefore also classifies those pairs against the rigid motion (same test)
and prints FCL's counts against that reference too (``rigid ref`` columns).

Our own answers are checked against the reference as well (misses, false hits, a
contact time later than a sampled intersection, a reported contact where the
boxes are visibly apart); every disagreement is printed with the seed, the pair
index and all inputs to 20 significant digits, and written to
``benchmarks/results/solver_disagreements.csv``.

Also printed: the cost of a Python no-op call with the same arguments and of a
trivial call into the compiled core, so the reader sees how much of the
single-query latency is Python, and the machine (platform, CPU, versions).

Targets (printed beside the measurements): single-query latency < 3 us; batch
>= 1,000,000 pairs/s for pairs that stay apart and >= 300,000 pairs/s for hits.

Run
---
    cd /work/main && PYTHONPATH=/work/main python3 benchmarks/solver.py            # ~1 min
    cd /work/main && PYTHONPATH=/work/main python3 benchmarks/solver.py --quick    # ~10 s

Options: ``--seed`` (default 12345), ``--n`` pairs per family for the single-query,
FCL and reference parts (default 2000; 800 with ``--quick``), ``--batch`` pairs per
family for the throughput part (default 20000; 10000 with ``--quick``), ``--samples``, ``--gjk``
(FCL's GJK solver, ``libccd`` = FCL's default, or ``indep``), ``--csv``.
The table is markdown and is also written to ``benchmarks/results/solver.csv``.
This is a benchmark, not a test: it asserts nothing about timings.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import math
import os
import platform
import statistics
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from bullet_boxccd import Box, QuadraticMotion, _core, time_of_impact, time_of_impact_batch

try:
    import fcl
except ImportError:  # the benchmark still runs, without the baseline
    fcl = None

try:
    from tqdm import tqdm as _tqdm

    def tqdm(it, **kw):
        return _tqdm(it, disable=not sys.stderr.isatty(), **kw)

except ImportError:

    def tqdm(it, **kw):
        return it


HERE = os.path.dirname(os.path.abspath(__file__))
FAMILIES = ("trans", "rot", "both")
TARGET_LATENCY_US = 3.0
TARGET_BATCH = {"apart": 1_000_000, "hit": 300_000}
SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)


# --------------------------------------------------------------------------------------
# pair generator
# --------------------------------------------------------------------------------------
def rodrigues(axis_angle: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors -> (..., 3, 3) rotation matrices."""
    theta = np.linalg.norm(axis_angle, axis=-1)
    k = axis_angle / np.where(theta > 0, theta, 1.0)[..., None]
    K = np.zeros(axis_angle.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -k[..., 2], k[..., 1]
    K[..., 1, 0], K[..., 1, 2] = k[..., 2], -k[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -k[..., 1], k[..., 0]
    s, c = np.sin(theta)[..., None, None], (1.0 - np.cos(theta))[..., None, None]
    return np.eye(3) + s * K + c * (K @ K)


def random_rotations(rng, n):
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def unit_vectors(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def rigid_pose(R0, p0, v, w, t):
    """Pose (n, 3, 4) at time t (scalar or (n,)) of the rigid motion: origin p0 + v t,
    orientation rot(w t) R0 (spin about the moving origin, world axes)."""
    t = np.broadcast_to(np.asarray(t, dtype=float), (len(R0),))
    P = np.empty((len(R0), 3, 4))
    P[:, :, :3] = rodrigues(w * t[:, None]) @ R0
    P[:, :, 3] = p0 + v * t[:, None]
    return P


def quadratic_coeffs(R0, p0, v, w):
    """(n, 3, 4, 4) coefficients of the quadratic through the rigid poses at t = 0, 1/2, 1
    (what ``QuadraticMotion.screw`` / ``.ballistic`` build, vectorized)."""
    n = len(R0)
    P = np.zeros((3, n, 4, 4))
    for i, t in enumerate((0.0, 0.5, 1.0)):
        P[i, :, :3, :] = rigid_pose(R0, p0, v, w, t)
        P[i, :, 3, 3] = 1.0
    c = np.empty((n, 3, 4, 4))
    c[:, 0] = P[0]
    c[:, 1] = 4.0 * P[1] - 3.0 * P[0] - P[2]
    c[:, 2] = 2.0 * (P[2] - 2.0 * P[1] + P[0])
    c[:, 1, 3] = 0.0
    c[:, 2, 3] = 0.0
    no_spin = ~np.any(w != 0.0, axis=1)  # exactly ballistic: drop the rounding noise of the fit
    c[no_spin, 2] = 0.0
    c[no_spin, 1, :3, :3] = 0.0
    return c


def make_pairs(seed: int, family: int, n: int) -> dict:
    """n seeded pairs of the given family (index into FAMILIES)."""
    rng = np.random.default_rng([seed, family])
    name = FAMILIES[family]
    ha = rng.uniform(0.05, 1.0, size=(n, 3))
    hb = rng.uniform(0.05, 1.0, size=(n, 3))
    r = np.linalg.norm(ha, axis=1) + np.linalg.norm(hb, axis=1)  # no overlap beyond distance r
    dist = rng.uniform(2.0, 6.0, size=n) * r
    start = unit_vectors(rng, n) * dist[:, None]
    aim = unit_vectors(rng, n) * (rng.uniform(0.0, 1.0, size=n) ** (1 / 3) * 0.8 * r)[:, None]
    speed = rng.uniform(0.3, 1.5, size=n)  # reaches the aim point at t = 1 / speed
    vb = (aim - start) * speed[:, None]
    Ra0 = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    pa0 = np.zeros((n, 3))
    va = np.zeros((n, 3))
    wa = np.zeros((n, 3))
    Rb0 = random_rotations(rng, n)
    wb = np.zeros((n, 3))
    if name in ("rot", "both"):
        wb = unit_vectors(rng, n) * rng.uniform(0.0, 0.95 * math.pi, size=n)[:, None]
    if name == "both":
        # A also moves: half the relative velocity each way, and spins
        Ra0 = random_rotations(rng, n)
        va = -0.5 * vb
        vb = 0.5 * vb
        wa = unit_vectors(rng, n) * rng.uniform(0.0, 0.95 * math.pi, size=n)[:, None]
    return dict(
        family=name,
        ha=ha,
        hb=hb,
        r=r,
        rigid_a=(Ra0, pa0, va, wa),
        rigid_b=(Rb0, start, vb, wb),
        ca=quadratic_coeffs(Ra0, pa0, va, wa),
        cb=quadratic_coeffs(Rb0, start, vb, wb),
    )


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


def check_against_api(p: dict, k: int = 5):
    """The vectorized generator must build exactly what the public constructors build."""
    for i in range(min(k, len(p["ha"]))):
        for which in ("a", "b"):
            R0, p0, v, w = (x[i] for x in p["rigid_" + which])
            pose = np.eye(4)
            pose[:3, :3], pose[:3, 3] = R0, p0
            if np.any(w != 0):
                m = QuadraticMotion.screw(pose, v, w)
            else:
                m = QuadraticMotion.ballistic(p0, v, rotation=R0)
            err = np.max(np.abs(m.coeffs - p["c" + which][i]))
            if err > 1e-12 * (1 + np.max(np.abs(m.coeffs))):
                raise RuntimeError(
                    f"generator disagrees with QuadraticMotion constructors (pair {i}, {which}): {err}"
                )


# --------------------------------------------------------------------------------------
# dense separating-axis reference
# --------------------------------------------------------------------------------------
def sat_gap(Ma: np.ndarray, Mb: np.ndarray, ha: np.ndarray, hb: np.ndarray) -> np.ndarray:
    """Separating-axis gap of two centred boxes (half extents ha, hb: (n, 3)) placed by
    affine maps Ma, Mb (n, T, 3, 4). Returns (n, T): > 0 separated (a lower bound on the
    distance), <= 0 intersecting."""
    ea = np.swapaxes(Ma[..., :3], -1, -2)  # (n, T, 3 edges, 3)
    eb = np.swapaxes(Mb[..., :3], -1, -2)
    axes = [
        np.cross(ea[..., 1, :], ea[..., 2, :]),
        np.cross(ea[..., 2, :], ea[..., 0, :]),
        np.cross(ea[..., 0, :], ea[..., 1, :]),
        np.cross(eb[..., 1, :], eb[..., 2, :]),
        np.cross(eb[..., 2, :], eb[..., 0, :]),
        np.cross(eb[..., 0, :], eb[..., 1, :]),
    ]
    scale = []
    for i in range(3):
        for j in range(3):
            axes.append(np.cross(ea[..., i, :], eb[..., j, :]))
            scale.append(np.linalg.norm(ea[..., i, :], axis=-1) * np.linalg.norm(eb[..., j, :], axis=-1))
    axes = np.stack(axes, axis=-2)  # (n, T, 15, 3)
    norm = np.linalg.norm(axes, axis=-1)
    scale = np.concatenate([norm[..., :6], np.stack(scale, axis=-1)], axis=-1)
    ok = norm > 1e-9 * scale  # near-parallel edges give no axis
    axes = axes / np.where(ok, norm, 1.0)[..., None]
    # projection of a box on a unit axis L: centre . L +- sum_k h_k |L . column_k|
    ra = np.abs(axes @ Ma[..., :3]) @ ha[:, None, :, None]  # (n, T, 15, 1)
    rb = np.abs(axes @ Mb[..., :3]) @ hb[:, None, :, None]
    d = (axes @ (Mb[..., 3] - Ma[..., 3])[..., None])[..., 0]  # (n, T, 15)
    gap = np.abs(d) - ra[..., 0] - rb[..., 0]
    gap = np.where(ok, gap, -np.inf)
    return gap.max(-1)


def quad_at(c: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(n, 3, 4, 4) coefficients at times t (n, T) -> (n, T, 3, 4)."""
    t = t[..., None, None]
    return c[:, None, 0, :3] + t * (c[:, None, 1, :3] + t * c[:, None, 2, :3])


def rigid_at(rigid, t: np.ndarray) -> np.ndarray:
    R0, p0, v, w = rigid
    n, T = t.shape
    P = np.empty((n, T, 3, 4))
    P[..., :3] = rodrigues(w[:, None, :] * t[..., None]) @ R0[:, None]
    P[..., 3] = p0[:, None, :] + v[:, None, :] * t[..., None]
    return P


def speed_bound_quad(c, h):
    """Upper bound over t in [0, 1] and the 8 vertices of |d/dt M(t) x| for (n, 3, 4, 4) c."""
    x = np.concatenate([SIGNS[None] * h[:, None, :], np.ones((len(h), 8, 1))], axis=-1)  # (n, 8, 4)
    d1 = np.linalg.norm(np.einsum("nij,nkj->nki", c[:, 1, :3], x), axis=-1)
    d2 = np.linalg.norm(np.einsum("nij,nkj->nki", c[:, 2, :3], x), axis=-1)
    return (d1 + 2.0 * d2).max(-1)


def speed_bound_rigid(rigid, h):
    _, _, v, w = rigid
    return np.linalg.norm(v, axis=1) + np.linalg.norm(w, axis=1) * np.linalg.norm(h, axis=1)


def reference(p: dict, samples: int, rigid: bool = False, chunk: int = 8, desc: str = "reference"):
    """Dense-sampling SAT classification. Returns dict with status (n,) in
    {'hit', 'miss', 'ambig'}, first intersecting sample time (NaN if none), min gap."""
    n = len(p["ha"])
    ts = np.linspace(0.0, 1.0, samples)
    first = np.full(n, np.nan)
    mingap = np.empty(n)
    for s in tqdm(range(0, n, chunk), desc=desc, leave=False, mininterval=1.0):
        e = min(n, s + chunk)
        T = np.broadcast_to(ts, (e - s, samples))
        q = subset(p, slice(s, e))
        if rigid:
            Ma, Mb = rigid_at(q["rigid_a"], T), rigid_at(q["rigid_b"], T)
        else:
            Ma, Mb = quad_at(q["ca"], T), quad_at(q["cb"], T)
        g = sat_gap(Ma, Mb, q["ha"], q["hb"])
        mingap[s:e] = g.min(1)
        hit = g <= 0.0
        any_hit = hit.any(1)
        first[s:e] = np.where(any_hit, ts[np.argmax(hit, axis=1)], np.nan)
    if rigid:
        vmax = speed_bound_rigid(p["rigid_a"], p["ha"]) + speed_bound_rigid(p["rigid_b"], p["hb"])
    else:
        vmax = speed_bound_quad(p["ca"], p["ha"]) + speed_bound_quad(p["cb"], p["hb"])
    margin = np.maximum(1e-3 * p["r"], vmax * (ts[1] - ts[0]) / 2.0)
    status = np.where(~np.isnan(first), "hit", np.where(mingap > margin, "miss", "ambig"))
    return dict(status=status, first=first, mingap=mingap, margin=margin)


def gap_at(p: dict, t: np.ndarray) -> np.ndarray:
    """SAT gap of each pair at its own time t (n,) under the quadratic motion."""
    T = t[:, None]
    return sat_gap(quad_at(p["ca"], T), quad_at(p["cb"], T), p["ha"], p["hb"])[:, 0]


# --------------------------------------------------------------------------------------
# our solver
# --------------------------------------------------------------------------------------
def our_objects(p: dict):
    """Public-API objects for every pair: (Box, QuadraticMotion, Box, QuadraticMotion)."""
    out = []
    for i in range(len(p["ha"])):
        out.append(
            (
                Box.centered(p["ha"][i]),
                QuadraticMotion(p["ca"][i]),
                Box.centered(p["hb"][i]),
                QuadraticMotion(p["cb"][i]),
            )
        )
    return out


def batch_args(p: dict):
    return (-p["ha"], p["ha"], p["ca"], -p["hb"], p["hb"], p["cb"])


def per_query_ns(fn, items, loops: int, repeats: int, desc: str):
    """Per item: median over ``repeats`` of (time of ``loops`` calls) / loops. Returns (n,) ns."""
    out = np.empty(len(items))
    clock = time.perf_counter_ns
    for i, args in enumerate(tqdm(items, desc=desc, leave=False, mininterval=1.0)):
        fn(*args)  # warm-up
        reps = []
        for _ in range(repeats):
            t0 = clock()
            for _ in range(loops):
                fn(*args)
            reps.append((clock() - t0) / loops)
        out[i] = statistics.median(reps)
    return out


def batch_throughput(args, threads: int = 1, repeats: int = 5) -> float:
    """Best-of-``repeats`` pairs/s of ``time_of_impact_batch`` over the whole arrays, split
    over ``threads`` Python threads (each calls it on its part: more than one thread
    scales only if the core releases the GIL)."""
    n = len(args[0])
    if n == 0:
        return float("nan")
    parts = [tuple(a[c] for a in args) for c in np.array_split(np.arange(n), threads)]
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(lambda part: time_of_impact_batch(*part), parts))  # warm-up
        best = math.inf
        for _ in range(repeats):
            t0 = time.perf_counter_ns()
            list(pool.map(lambda part: time_of_impact_batch(*part), parts))
            best = min(best, time.perf_counter_ns() - t0)
    return n / (best * 1e-9)


# --------------------------------------------------------------------------------------
# FCL
# --------------------------------------------------------------------------------------
FCL_MOTIONS = ("trans", "linear", "screw")


def fcl_setup(p: dict, motion: str, gjk: str):
    """Per pair: (o1, tf1_end, o2, tf2_end, request) for fcl.continuousCollide."""
    mt = {
        "trans": fcl.CCDMotionType.CCDM_TRANS,
        "linear": fcl.CCDMotionType.CCDM_LINEAR,
        "screw": fcl.CCDMotionType.CCDM_SCREW,
    }[motion]
    gst = {"libccd": fcl.GJKSolverType.GST_LIBCCD, "indep": fcl.GJKSolverType.GST_INDEP}[gjk]
    request = fcl.ContinuousCollisionRequest(
        num_max_iterations=100,
        toc_err=1e-6,
        ccd_motion_type=mt,
        gjk_solver_type=gst,
        ccd_solver_type=fcl.CCDSolverType.CCDC_CONSERVATIVE_ADVANCEMENT,
    )
    n = len(p["ha"])
    A0, A1 = rigid_pose(*p["rigid_a"], 0.0), rigid_pose(*p["rigid_a"], 1.0)
    B0, B1 = rigid_pose(*p["rigid_b"], 0.0), rigid_pose(*p["rigid_b"], 1.0)
    items = []
    for i in range(n):
        ga = fcl.Box(*(2.0 * p["ha"][i]))
        gb = fcl.Box(*(2.0 * p["hb"][i]))
        items.append(
            (
                fcl.CollisionObject(ga, fcl.Transform(A0[i, :, :3], A0[i, :, 3])),
                fcl.Transform(A1[i, :, :3], A1[i, :, 3]),
                fcl.CollisionObject(gb, fcl.Transform(B0[i, :, :3], B0[i, :, 3])),
                fcl.Transform(B1[i, :, :3], B1[i, :, 3]),
                request,
            )
        )
    return items


def fcl_query(o1, tf1, o2, tf2, request):
    result = fcl.ContinuousCollisionResult()
    fcl.continuousCollide(o1, tf1, o2, tf2, request, result)
    return result


def fcl_answers(items):
    """(n,) contact time (NaN = no hit), (n,) bool error."""
    t = np.full(len(items), np.nan)
    err = np.zeros(len(items), dtype=bool)
    for i, it in enumerate(items):
        try:
            r = fcl_query(*it)
            if r.is_collide:
                t[i] = r.time_of_contact
        except Exception:
            err[i] = True
    return t, err


def fcl_safe(o1, tf1, o2, tf2, request):
    try:
        return fcl_query(o1, tf1, o2, tf2, request)
    except Exception:
        return None


# --------------------------------------------------------------------------------------
# report helpers
# --------------------------------------------------------------------------------------
def machine_info() -> list[str]:
    cpu = platform.processor() or "?"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    fcl_version = getattr(fcl, "__version__", "?") if fcl is not None else "not installed"
    with open(_core.__file__, "rb") as f:
        core_sha = hashlib.sha256(f.read()).hexdigest()[:12]
    core_time = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(os.path.getmtime(_core.__file__)))
    return [
        f"platform: {platform.platform()}",
        f"cpu: {cpu} ({os.cpu_count()} logical cpus)",
        f"python {platform.python_version()}, numpy {np.__version__}, python-fcl {fcl_version}, "
        f"bullet_boxccd core {os.path.basename(_core.__file__)} (sha256 {core_sha}, built {core_time})",
    ]


def fmt(x, kind):
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    if kind == "us":
        return f"{x:.2f}"
    if kind == "rate":
        return f"{x:,.0f}"
    if kind == "dt":
        return f"{x:.1e}"
    return str(x)


def g20(x) -> str:
    return f"{float(x):.20g}"


def reproduce_line(p: dict, i: int) -> str:
    ha, hb, ca, cb = p["ha"][i], p["hb"][i], p["ca"][i], p["cb"][i]

    def L(a):
        return "[" + ", ".join(L(x) if isinstance(x, np.ndarray) else g20(x) for x in a) + "]"

    return (
        f"a = Box.centered({L(ha)}); b = Box.centered({L(hb)}); "
        f"ma = QuadraticMotion(np.array({L(ca)})); mb = QuadraticMotion(np.array({L(cb)}))"
    )


# --------------------------------------------------------------------------------------
# main
# --------------------------------------------------------------------------------------
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="a ~20 s version (fewer pairs, loops, samples)")
    ap.add_argument("--seed", type=int, default=12345)
    ap.add_argument("--n", type=int, default=None, help="pairs per family for single-query / FCL / reference")
    ap.add_argument("--batch", type=int, default=None, help="pairs per family for the batch throughput")
    ap.add_argument("--samples", type=int, default=None, help="reference samples over t in [0, 1]")
    ap.add_argument("--gjk", choices=("libccd", "indep"), default="libccd", help="FCL's GJK solver")
    ap.add_argument("--csv", default=os.path.join(HERE, "results", "solver.csv"))
    args = ap.parse_args(argv)
    n = args.n or (800 if args.quick else 2000)
    nbatch = args.batch or (10000 if args.quick else 20000)
    samples = args.samples or (1000 if args.quick else 2000)
    loops, repeats = (5, 3) if args.quick else (20, 5)
    fcl_loops, fcl_repeats = (1, 3) if args.quick else (3, 3)
    t_start = time.perf_counter()

    info = machine_info()
    print("# bullet_boxccd solver benchmark")
    for line in info:
        print(line)
    print(
        f"seed {args.seed}, {n} pairs per family (single / FCL / reference), {nbatch} per family (batch), "
        f"{samples} reference samples; FCL: conservative advancement, GJK {args.gjk}, "
        f"num_max_iterations=100, toc_err=1e-6"
    )

    # ---- Python overhead baselines ----
    a0, b0 = Box.centered((0.5, 0.5, 0.5)), Box.centered((0.5, 0.5, 0.5))
    m0, m1 = QuadraticMotion.static(), QuadraticMotion.ballistic((3.0, 0.0, 0.0), (-1.0, 0.0, 0.0))

    def noop(a, ma, b, mb):
        return None

    def median_ns(fn, args):
        return statistics.median(per_query_ns(fn, [args] * 200, 50, 3, "overhead"))

    ov_noop = median_ns(noop, (a0, m0, b0, m1))
    ov_api = median_ns(time_of_impact, (a0, m0, b0, m1))
    # the raw core call, with exactly the arguments the public wrapper passes (captured, so this
    # does not depend on the private signature of _core.solve)
    captured = []
    solve = _core.solve

    def capture(*a):
        captured.append(a)
        return solve(*a)

    _core.solve = capture
    try:
        time_of_impact(a0, m0, b0, m1)
    finally:
        _core.solve = solve
    ov_raw = median_ns(solve, captured[0]) if captured else float("nan")
    # a trivial call into the compiled module (whichever small helper it exports)
    ov_core, core_fn = float("nan"), "-"
    for name, fn_args in (("feature_name", ((1, 0, -1),)), ("check_motion", (m0.coeffs, "m"))):
        if hasattr(_core, name):
            ov_core, core_fn = median_ns(getattr(_core, name), fn_args), f"_core.{name}"
            break
    print(
        f"call overhead (median per call): Python no-op function (4 args) {ov_noop / 1e3:.3f} us; "
        f"trivial nanobind call ({core_fn}) {ov_core / 1e3:.3f} us; "
        f"_core.solve on a simple miss {ov_raw / 1e3:.3f} us vs time_of_impact {ov_api / 1e3:.3f} us "
        f"(the difference is the Python wrapper)"
    )

    rows = [
        dict(family="-", cls=cls, method=method, latency_us=ns / 1e3, rate=1e9 / ns)
        for cls, method, ns in (
            ("-", "Python no-op call (4 args)", ov_noop),
            ("-", f"trivial nanobind call ({core_fn})", ov_core),
            ("apart", "_core.solve (no wrapper), simple miss", ov_raw),
            ("apart", "time_of_impact, same simple miss", ov_api),
        )
    ]
    disagreements = []
    notes = []
    for fam in range(len(FAMILIES)):
        fname = FAMILIES[fam]
        P = make_pairs(args.seed, fam, max(n, nbatch))
        check_against_api(P)
        # batch classification of the big set (also gives the hit / apart split for throughput)
        t_all = time_of_impact_batch(*batch_args(P))
        big_hit = ~np.isnan(t_all)
        p = subset(P, slice(0, n))
        t_ours = t_all[:n]
        ours_hit = ~np.isnan(t_ours)
        objs = our_objects(p)
        # cross-check: single and batch calls must agree
        t_single = np.array([(lambda c: np.nan if c is None else c.t)(time_of_impact(*o)) for o in objs])
        same = (np.isnan(t_single) == np.isnan(t_ours)) & (np.isnan(t_ours) | (t_single == t_ours))
        for i in np.nonzero(~same)[0]:
            why = f"single {float(t_single[i])!r} batch {float(t_ours[i])!r}"
            disagreements.append((fname, int(i), "single != batch", why, p))

        # reference (quadratic motion) and checks of our answers
        ref = reference(p, samples, desc=f"{fname}: reference")
        st = ref["status"]
        ref_rigid = ref
        if fname != "trans":
            ref_rigid = reference(p, samples, rigid=True, desc=f"{fname}: rigid reference")
        g_at = np.full(n, np.nan)
        idx = np.nonzero(ours_hit)[0]
        if len(idx):
            g_at[idx] = gap_at(subset(p, idx), t_ours[idx])
        for i in range(n):
            why = None
            if st[i] == "hit" and not ours_hit[i]:
                why = f"ours: no hit; reference: intersecting at sample t={ref['first'][i]:.6g}"
            elif st[i] == "miss" and ours_hit[i]:
                why = (
                    f"ours: hit at t={float(t_ours[i])!r}; reference: min gap {ref['mingap'][i]:.3e}"
                    f" > margin {ref['margin'][i]:.3e}"
                )
            elif ours_hit[i] and st[i] == "hit" and ref["first"][i] < t_ours[i] - 1e-12:
                why = f"ours: t={float(t_ours[i])!r} later than intersecting sample t={ref['first'][i]:.17g}"
            elif ours_hit[i] and g_at[i] > 1e-6 * p["r"][i]:
                why = f"ours: t={float(t_ours[i])!r} but SAT gap there is {g_at[i]:.3e} (r={p['r'][i]:.3g})"
            if why:
                disagreements.append((fname, i, "ours vs reference", why, p))

        # FCL answers (once per motion type)
        fcl_res = {}
        if fcl is not None:
            for mo in FCL_MOTIONS:
                items = fcl_setup(p, mo, args.gjk)
                t_f, err_f = fcl_answers(items)
                fcl_res[mo] = (items, t_f, err_f)
                zero = int(np.sum((t_f == 0.0) & (t_ours != 0.0)))
                if zero:
                    notes.append(
                        f"{fname}: fcl CA {mo} answered t = 0 for {zero} of {n} pairs that start apart"
                    )

        for cls in ("hit", "apart"):
            sel = ours_hit if cls == "hit" else ~ours_hit
            ids = np.nonzero(sel)[0]
            ns = len(ids)
            n_ambig = int(np.sum(st[ids] == "ambig"))
            n_ambig_rigid = int(np.sum(ref_rigid["status"][ids] == "ambig"))

            def counts(answer_hit, status):
                miss = int(np.sum((status[ids] == "hit") & ~answer_hit[ids]))
                false = int(np.sum((status[ids] == "miss") & answer_hit[ids]))
                return miss, false

            lat = per_query_ns(time_of_impact, [objs[i] for i in ids], loops, repeats, f"{fname}/{cls}: ours")
            m_o, f_o = counts(ours_hit, st)
            base = dict(family=fname, cls=cls, pairs=ns, ambig=n_ambig)
            rows.append(
                dict(
                    base,
                    method="ours time_of_impact",
                    latency_us=statistics.median(lat) / 1e3 if ns else float("nan"),
                    p90_us=float(np.percentile(lat, 90)) / 1e3 if ns else float("nan"),
                    mean_us=float(np.mean(lat)) / 1e3 if ns else float("nan"),
                    rate=1e9 / statistics.median(lat) if ns else float("nan"),
                    target=f"latency < {TARGET_LATENCY_US:g} us",
                    misses=m_o,
                    false_hits=f_o,
                    errors=0,
                )
            )
            bsel = big_hit if cls == "hit" else ~big_hit
            bargs = tuple(x[bsel] for x in batch_args(P))
            thr = batch_throughput(bargs)
            rows.append(
                dict(
                    family=fname,
                    cls=cls,
                    pairs=int(bsel.sum()),
                    method="ours time_of_impact_batch",
                    latency_us=1e6 / thr,
                    rate=thr,
                    target=f">= {TARGET_BATCH[cls]:,} pairs/s",
                )
            )
            threads = min(os.cpu_count() or 1, 4)
            if threads > 1:
                thr_t = batch_throughput(bargs, threads)
                rows.append(
                    dict(
                        family=fname,
                        cls=cls,
                        pairs=int(bsel.sum()),
                        method=f"ours time_of_impact_batch, {threads} threads",
                        latency_us=1e6 / thr_t,
                        rate=thr_t,
                        target=f"{thr_t / thr:.2f}x one thread",
                    )
                )
            for mo in FCL_MOTIONS if fcl is not None else ():
                items, t_f, err_f = fcl_res[mo]
                sub = [items[i] for i in ids]
                lat_f = per_query_ns(fcl_safe, sub, fcl_loops, fcl_repeats, f"{fname}/{cls}: fcl {mo}")
                f_hit = ~np.isnan(t_f)
                m_f, f_f = counts(f_hit & ~err_f, st)
                m_r, f_r = counts(f_hit & ~err_f, ref_rigid["status"])
                both = ids[ours_hit[ids] & f_hit[ids]]
                dt = np.abs(t_f[both] - t_ours[both])
                rows.append(
                    dict(
                        base,
                        method=f"fcl CA {mo}",
                        latency_us=statistics.median(lat_f) / 1e3 if ns else float("nan"),
                        p90_us=float(np.percentile(lat_f, 90)) / 1e3 if ns else float("nan"),
                        mean_us=float(np.mean(lat_f)) / 1e3 if ns else float("nan"),
                        rate=1e9 / statistics.median(lat_f) if ns else float("nan"),
                        dt_median=float(np.median(dt)) if len(dt) else float("nan"),
                        dt_max=float(np.max(dt)) if len(dt) else float("nan"),
                        within_1e3=f"{np.mean(dt <= 1e-3) * 100:.0f}%" if len(dt) else "-",
                        misses=m_f,
                        false_hits=f_f,
                        errors=int(err_f[ids].sum()),
                        misses_rigid=m_r if fname != "trans" else None,
                        false_hits_rigid=f_r if fname != "trans" else None,
                        ambig_rigid=n_ambig_rigid if fname != "trans" else None,
                    )
                )
        notes.append(
            f"{fname}: {n} pairs, ours hit {int(ours_hit.sum())}, apart {int((~ours_hit).sum())}; reference "
            f"hit {int(np.sum(st == 'hit'))}, miss {int(np.sum(st == 'miss'))}, "
            f"ambiguous {int(np.sum(st == 'ambig'))}; "
            f"initial contacts {int(np.sum(t_ours == 0.0))}; SAT gap at our t / r in "
            f"[{np.nanmin(g_at / p['r']):.2e}, {np.nanmax(g_at / p['r']):.2e}] (> 0: early, as guaranteed); "
            f"batch set {len(t_all)} pairs, {int(big_hit.sum())} hit"
        )

    # ---- table ----
    cols = [
        ("family", "family", None),
        ("cls", "class", None),
        ("method", "method", None),
        ("pairs", "pairs", None),
        ("latency_us", "median us/query", "us"),
        ("p90_us", "p90 us", "us"),
        ("mean_us", "mean us", "us"),
        ("rate", "queries/s", "rate"),
        ("target", "target", None),
        ("dt_median", "median abs(t-ours)", "dt"),
        ("dt_max", "max abs(t-ours)", "dt"),
        ("within_1e3", "abs dt<=1e-3", None),
        ("misses", "misses", None),
        ("false_hits", "false hits", None),
        ("errors", "errors", None),
        ("ambig", "ambig", None),
        ("misses_rigid", "misses (rigid ref)", None),
        ("false_hits_rigid", "false hits (rigid ref)", None),
        ("ambig_rigid", "ambig (rigid ref)", None),
    ]
    for r in rows:
        r.setdefault("target", "")
        if r["method"].startswith("ours") and "batch" not in r["method"]:
            r["target"] += " " + ("MET" if r["latency_us"] < TARGET_LATENCY_US else "not met")
        if "batch" in r["method"] and "threads" not in r["method"]:  # the targets are per core
            r["target"] += " " + ("MET" if r["rate"] >= TARGET_BATCH[r["cls"]] else "not met")
    print()
    print("| " + " | ".join(h for _, h, _ in cols) + " |")
    print("|" + "|".join("---" for _ in cols) + "|")
    for r in rows:
        print("| " + " | ".join(fmt(r.get(k), kind) for k, _, kind in cols) + " |")
    print()
    print(
        "class = our solver's answer. misses / false hits: against the dense SAT reference on the quadratic "
        "motion our solver gets (ambiguous pairs excluded); '(rigid ref)': the same test on the rigid motion "
        "FCL's end poses describe (translate + spin about the moving origin, what CCDM_LINEAR follows; "
        "CCDM_TRANS ignores the spin and CCDM_SCREW takes another path between the same poses). errors: FCL "
        "exceptions. Batch rows: queries/s = pairs/s of one time_of_impact_batch call (best of 5, one core); "
        "'N threads': the same arrays split over N Python threads (it scales only because the core releases "
        "the GIL); "
        "us/query = its inverse (a mean: compare with 'mean us' of the single rows). Rows with family '-': "
        "call-overhead baselines (a Python no-op with the same 4 arguments, a trivial call into the compiled "
        "core, and the raw core call vs the public wrapper on one easy miss). Caveats on the baseline: "
        "FCL's InterpMotion(tf1, tf2) constructor (CCDM_LINEAR) leaves its reference point uninitialized "
        "(fcl interp_motion-inl.h), so 'fcl CA linear' can change from run to run (seen: every pair "
        "reported hitting at t = 0); CCDM_SCREW between two poses with no relative rotation does not "
        "follow the translation (see the trans rows)."
    )
    for line in notes:
        print("  " + line)

    # ---- disagreements of our solver ----
    print()
    if disagreements:
        print(f"!! {len(disagreements)} disagreement(s) of our solver (seed {args.seed}):")
        for fname, i, kind, why, p in disagreements[:20]:
            print(f"  family {fname} (generator index {FAMILIES.index(fname)}), pair {i}: {kind}: {why}")
            print("    " + reproduce_line(p, i))
    else:
        print("our solver agrees with the dense-sampling reference on all unambiguous pairs; single == batch")

    # ---- CSV ----
    os.makedirs(os.path.dirname(os.path.abspath(args.csv)), exist_ok=True)
    with open(args.csv, "w", newline="") as f:
        w = csv.writer(f)
        meta = dict(seed=args.seed, n=n, batch=nbatch, samples=samples, fcl_gjk=args.gjk)
        meta["machine"] = " | ".join(info)
        w.writerow([k for k, _, _ in cols] + list(meta))
        for r in rows:
            w.writerow(["" if r.get(k) is None else r.get(k) for k, _, _ in cols] + list(meta.values()))
    dpath = os.path.join(os.path.dirname(os.path.abspath(args.csv)), "solver_disagreements.csv")
    if disagreements:
        with open(dpath, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["seed", "family", "pair", "kind", "why", "ha", "hb", "coeffs_a", "coeffs_b"])
            for fname, i, kind, why, p in disagreements:
                w.writerow(
                    [args.seed, fname, i, kind, why]
                    + [" ".join(g20(x) for x in p[k][i].ravel()) for k in ("ha", "hb", "ca", "cb")]
                )
    elif os.path.exists(dpath):
        os.remove(dpath)
    print(f"\nwrote {args.csv}" + (f" and {dpath}" if disagreements else ""))
    if machine_info()[2] != info[2]:
        print("!! the compiled core changed on disk during the run: timings mix two builds; run again")
    print(f"total time {time.perf_counter() - t_start:.1f} s")


if __name__ == "__main__":
    main()
