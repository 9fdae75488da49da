"""One real pybullet client, run unedited in this process, in one of three variants
(the harness of benchmarks/clients.py and tests/test_clients.py, which run each variant
in its own subprocess so that a crash is a result, not a dead harness):

* ``bare``: pybullet alone; bullet_boxccd is never imported (the reference trajectory),
* ``plain``: bullet_boxccd imported (its journal hooks wrap pybullet's world-changing
  functions), every ``stepSimulation`` timed around pybullet's own function,
* ``ccd``: every ``stepSimulation`` of client c after the env's first ``reset()`` (for a
  script: from its first step on) goes to ``BoxCCD(c).step()``, the BoxCCD made for c at
  that first call, and is timed around it.

Clients: pybullet_envs' gym envs (``CLIENTS[name] = Env(gym id, ...)``) and
pybullet_examples' scripts (``Script(file, ...)``).

How the calls are routed, without editing pybullet's files: the module attribute
``pybullet.stepSimulation`` is replaced by a builtin (``bullet_boxccd._core.as_builtin``,
as the package's own hooks are) so that pybullet_utils' ``BulletClient``, which passes its
client id to builtins only, still passes ``physicsClientId``; a call for client c reads c
from its arguments. The plugin steps through pybullet's original (``_hooks.raw``), so the
router never sees the plugin's own steps (no recursion; ``Router.ccd_inner`` counts any
that would reach it, and the runner fails if one does).

Scripts run through ``runpy`` with pybullet's GUI emulated in DIRECT: ``connect(GUI)`` is
``connect(DIRECT)``, ``connect(SHARED_MEMORY)`` finds no server (-1), ``time.sleep`` returns
at once, GUI sliders (``addUserDebugParameter``) read their start value, as in a GUI
nobody touches. A script stops after a budget of steps (``StepBudget``, raised from the
router after the step is recorded) or at its own end.

A BulletClient env runs beside an empty world on client 0 (its own client is then 1),
so that the router is seen to read the client from each call.

Determinism: ``random.seed``, ``np.random.seed`` and ``env.seed(seed)`` before the first
reset; actions from ``np.random.default_rng(seed)``. Recorded per env step (script:
per step): the observation (envs), every body's base pose and every link's frame as
pybullet caches it (read-only reads: no forward kinematics), and the step times.

Usage: python benchmarks/_clients_run.py CLIENT VARIANT --steps N --seed S --out FILE.pkl
[--profile FILE.prof] [--categories]; FILE.pkl holds the ``Record``'s fields as a dict.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # no spinning BLAS threads on a 2-core machine

import argparse  # noqa: E402
import pickle  # noqa: E402
import random  # noqa: E402
import runpy  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
import warnings  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402

import numpy as np  # noqa: E402

VARIANTS = ("bare", "plain", "ccd")


@dataclass(frozen=True)
class Env:
    """A gym env of pybullet_envs. ``steps``: default horizon (env steps) of the full run
    (an env step may take several stepSimulation calls: Racecar's action repeat is 50)."""

    gym_id: str
    steps: int = 1000
    quick: int = 200
    module_client: bool = False  # steps pybullet's module functions, on client 0 (else a BulletClient)


@dataclass(frozen=True)
class Script:
    """A pybullet_examples script. ``tick``: the pybullet function whose calls are the
    loop's steps (a script whose loop never steps is bounded by another call it makes
    every iteration). ``note``: what the script builds."""

    file: str
    steps: int = 1000
    quick: int = 200
    tick: str = "stepSimulation"
    note: str = ""


CLIENTS = {
    "CartPoleBulletEnv-v1": Env("CartPoleBulletEnv-v1"),
    "KukaBulletEnv-v0": Env("KukaBulletEnv-v0", module_client=True),
    "RacecarBulletEnv-v0": Env("RacecarBulletEnv-v0", steps=100, quick=8),  # 50 stepSimulation per env step
    "MinitaurBulletEnv-v0": Env("MinitaurBulletEnv-v0"),
    "HopperBulletEnv-v0": Env("HopperBulletEnv-v0"),
    "AntBulletEnv-v0": Env("AntBulletEnv-v0"),
    "Walker2DBulletEnv-v0": Env("Walker2DBulletEnv-v0"),
    "HalfCheetahBulletEnv-v0": Env("HalfCheetahBulletEnv-v0"),
    "HumanoidBulletEnv-v0": Env("HumanoidBulletEnv-v0", steps=1000, quick=100),
    "createObstacleCourse.py": Script("createObstacleCourse.py", note="static box course, box links on motors"),
    "snake.py": Script("snake.py", note="36-link box snake, maximal coordinates"),
    "pdControl.py": Script("pdControl.py", note="4 cartpoles, PD plugin, setTimeStep every step"),
    "switchConstraintSolver.py": Script("switchConstraintSolver.py", note="stack of 10 small cubes, Dantzig"),
    "video_sync_mp4.py": Script("video_sync_mp4.py", steps=720, quick=200, note="r2d2 dropped from 45 m"),
    "createMultiBodyBatch.py": Script("createMultiBodyBatch.py", steps=100, quick=10,
                                      note="10240 static boxes, one batch"),
    "humanoidMotionCapture.py": Script("humanoidMotionCapture.py", steps=600, quick=100,
                                       note="5 humanoids (box feet), explicit/stable PD"),
    "deformable_anchor.py": Script("deformable_anchor.py", steps=300, quick=50,
                                   note="cloth anchored to a maximal-coordinate cube"),
    "getClosestPoints.py": Script("getClosestPoints.py", steps=200, quick=50, tick="isConnected",
                                  note="no stepSimulation: a box teleported every loop"),
}


def examples_dir():
    import pybullet_examples

    return os.path.dirname(os.path.abspath(pybullet_examples.__file__))


class StepBudget(BaseException):
    """Raised by the router when a script has taken its budget of steps."""


# --------------------------------------------------------------- the router
@dataclass
class Record:
    """What one variant of one client did (pickled for the harness)."""

    client: str
    variant: str
    seed: int
    steps: int  # env steps (script: ticks) asked for
    env_steps: int = 0  # taken
    sim_steps: int = 0  # stepSimulation calls routed (after arming)
    obs: list = field(default_factory=list)  # per env step: the observation (float64)
    dones: list = field(default_factory=list)
    poses: list = field(default_factory=list)  # per env step / tick: every body's and link's frame (float64)
    step_ns: list = field(default_factory=list)  # per routed stepSimulation: wall time (ns)
    env_ns: list = field(default_factory=list)  # per env.step (envs): wall time (ns), whatever the variant
    step_swept: list = field(default_factory=list)  # per routed stepSimulation (ccd): boxes it swept
    first_act: int = -1  # (ccd) index in ``poses`` of the first env step / tick in which BoxCCD took a contact back
    boxccd_warnings: list = field(default_factory=list)  # (message, filename:lineno)
    other_warnings: list = field(default_factory=list)  # from bullet_boxccd, not BoxCCDWarning
    stats: dict = field(default_factory=dict)  # per client id: ccd.stats as a dict
    summaries: dict = field(default_factory=dict)  # per client id: ccd.summary()
    construct_s: dict = field(default_factory=dict)  # per client id: BoxCCD() seconds
    categories: dict = field(default_factory=dict)  # callee -> (calls, ns) inside BoxCCD.step (--categories)
    step_groups: list = field(default_factory=list)  # per step (--categories): ns (total, stepSimulation,
    #                                                  other pybullet, _core)
    ccd_inner: int = 0  # router calls made from inside BoxCCD.step (must stay 0)
    error: str = ""
    ended: str = ""  # how the run ended: "steps", "budget", "script end"
    wall_s: float = 0.0


def _client_of(args, kwargs):
    if "physicsClientId" in kwargs:
        return int(kwargs["physicsClientId"])
    return int(args[0]) if args else 0


class Router:
    """Replaces ``pybullet.stepSimulation`` for this process (see the module docstring)."""

    def __init__(self, variant, record, on_step=None, budget=None, ccd_kwargs=None, profiler=None):
        import pybullet

        self.p = pybullet
        self.variant, self.record, self.on_step, self.budget = variant, record, on_step, budget
        self.ccd_kwargs = ccd_kwargs or {}
        self.profiler = profiler
        self.armed = False
        self.ccds = {}
        self.inside = False
        self.previous = pybullet.stepSimulation  # the package's journal wrapper, or pybullet's own
        originals = getattr(pybullet, "_bullet_boxccd_originals", None)
        self.original = originals["stepSimulation"] if originals else pybullet.stepSimulation
        if variant == "bare":
            # No bullet_boxccd: a Python function is not a builtin, so a BulletClient would not
            # pass its id to it; bare envs are not routed (see run_env), scripts use client 0.
            wrapper = self._call
        else:
            from bullet_boxccd import _core

            wrapper = _core.as_builtin(self._call, "stepSimulation", self.previous.__doc__ or "")
        pybullet.stepSimulation = wrapper
        self.categories = Categories(self) if _CATEGORIES and variant == "ccd" else None

    def _call(self, *args, **kwargs):
        if self.inside:
            self.record.ccd_inner += 1
            return self.original(*args, **kwargs)
        if not self.armed:
            return self.previous(*args, **kwargs)
        cid = _client_of(args, kwargs)
        if self.variant == "ccd":
            ccd = self.ccds.get(cid)
            if ccd is None:
                from bullet_boxccd import BoxCCD

                t0 = time.perf_counter()
                ccd = self.ccds[cid] = BoxCCD(cid, **self.ccd_kwargs)
                self.record.construct_s[cid] = time.perf_counter() - t0
            swept, rewinds = ccd.stats.swept_boxes, ccd.stats.rewinds
            self.inside = True
            try:
                if self.profiler is not None:
                    self.profiler.enable()
                t0 = time.perf_counter_ns()
                ccd.step()
                t1 = time.perf_counter_ns()
                if self.profiler is not None:
                    self.profiler.disable()
            finally:
                self.inside = False
            self.record.step_swept.append(ccd.stats.swept_boxes - swept)
            if ccd.stats.rewinds > rewinds and self.record.first_act < 0:
                self.record.first_act = len(self.record.poses)
            if self.categories is not None:
                self.record.step_groups.append((t1 - t0, *self.categories.now))
                self.categories.now[:] = [0, 0, 0]
            result = None
        else:
            t0 = time.perf_counter_ns()
            result = self.original(*args, **kwargs)
            t1 = time.perf_counter_ns()
        self.record.step_ns.append(t1 - t0)
        self.record.sim_steps += 1
        if self.on_step is not None:
            self.on_step(cid)
        if self.budget is not None and self.record.sim_steps >= self.budget:
            raise StepBudget()
        return result


# -------------------------------------------------------------- recording
def connected_clients(p, upto=16):
    return [c for c in range(upto) if p.getConnectionInfo(c)["isConnected"]]


def frames(p, cid):
    """Every body's base pose and every link's cached world frame (no forward kinematics:
    the read changes nothing), as one float64 vector."""
    out = []
    for i in range(p.getNumBodies(physicsClientId=cid)):
        b = p.getBodyUniqueId(i, physicsClientId=cid)
        pos, orn = p.getBasePositionAndOrientation(b, physicsClientId=cid)
        out += [b, *pos, *orn]
        n = p.getNumJoints(b, physicsClientId=cid)
        if n:
            for s in p.getLinkStates(b, list(range(n)), physicsClientId=cid) or ():
                if s is not None:
                    out += [*s[4], *s[5]]
    return np.asarray(out, dtype=np.float64)


def all_frames(p):
    vs = [frames(p, c) for c in connected_clients(p)]
    return np.concatenate(vs) if vs else np.zeros(0)


def sample(space, rng):
    from gym import spaces

    if isinstance(space, spaces.Discrete):
        return int(rng.integers(space.n))
    if isinstance(space, spaces.Box):
        return rng.uniform(space.low, space.high).astype(space.dtype)
    raise TypeError(f"action space {space!r}")


def _warnings_into(record, caught):
    for w in caught:
        cat = w.category.__name__
        where = f"{os.path.basename(w.filename)}:{w.lineno}"
        if cat == "BoxCCDWarning":
            record.boxccd_warnings.append((str(w.message), where))
        elif "bullet_boxccd" in (w.filename or "") or "boxccd" in str(w.message).lower():
            record.other_warnings.append((cat, str(w.message), where))


def _stats(record, router):
    from dataclasses import asdict

    if router.categories is not None:
        c = router.categories
        record.categories = {k: (c.calls[k], c.ns[k]) for k in c.ns}
    for cid, ccd in router.ccds.items():
        s = asdict(ccd.stats)
        s["outcomes"] = np.asarray(ccd.stats.outcomes).tolist()
        record.stats[cid] = s
        try:
            record.summaries[cid] = ccd.summary()
        except Exception as e:  # a disconnected client
            record.summaries[cid] = f"(summary failed: {e!r})"


# -------------------------------------------------------------------- runs
def run_env(record, spec, variant, steps, seed, profiler=None):
    import gym
    import pybullet as p

    router = None if variant == "bare" else Router(variant, record, profiler=profiler)
    import pybullet_envs  # noqa: F401  (registers the envs)

    if not spec.module_client:
        # An empty world on client 0 first, in every variant: the env's BulletClient gets
        # another id, which the router must read from the call (a step routed to client 0
        # would leave the env's world unstepped).
        p.connect(p.DIRECT)
    random.seed(seed)
    np.random.seed(seed)
    env = gym.make(spec.gym_id)
    env.seed(seed)
    env.reset()
    if router is not None:
        router.armed = True
    rng = np.random.default_rng(seed)
    record.ended = "steps"
    for i in range(steps):
        action = sample(env.action_space, rng)
        t0 = time.perf_counter_ns()
        obs, _, done, _ = env.step(action)
        record.env_ns.append(time.perf_counter_ns() - t0)
        record.env_steps += 1
        record.obs.append(np.asarray(obs, dtype=np.float64).ravel())
        record.dones.append(bool(done))
        record.poses.append(all_frames(p))
        if done and i + 1 < steps:
            env.reset()
    if router is not None:
        _stats(record, router)
    return env


_SLIDERS = []


def _emulate_gui(p):
    """pybullet's GUI as a DIRECT client sees it when nobody touches the window."""
    connect = p.connect

    def connect_direct(mode, *args, **kwargs):
        if mode in (p.SHARED_MEMORY, getattr(p, "SHARED_MEMORY_GUI", -99), getattr(p, "SHARED_MEMORY_SERVER", -99)):
            return -1  # no server to share memory with
        return connect(p.DIRECT)

    def add_slider(paramName, rangeMin, rangeMax, startValue, physicsClientId=0):
        _SLIDERS.append(float(startValue))
        return len(_SLIDERS) - 1

    def read_slider(itemUniqueId, physicsClientId=0):
        return _SLIDERS[int(itemUniqueId)]

    p.connect = connect_direct
    p.addUserDebugParameter = add_slider
    p.readUserDebugParameter = read_slider
    time.sleep = lambda s: None


def run_script(record, spec, variant, steps, seed, profiler=None):
    import pybullet as p

    _emulate_gui(p)
    random.seed(seed)
    np.random.seed(seed)

    def on_step(cid):
        record.env_steps += 1
        record.poses.append(all_frames(p))

    if spec.tick == "stepSimulation":
        router = Router(variant, record, on_step=on_step, budget=steps, profiler=profiler)
        router.armed = True
    else:  # the loop never steps: count the ticks (nothing to route)
        router = None if variant == "bare" else Router(variant, record, profiler=profiler)
        tick = getattr(p, spec.tick)
        count = [0]

        def ticked(*args, **kwargs):
            if count[0] >= steps:
                raise StepBudget()
            count[0] += 1
            result = tick(*args, **kwargs)
            if count[0] > 1:  # the state the previous loop iteration left
                on_step(0)
            return result

        setattr(p, spec.tick, ticked)
        if router is not None:
            router.armed = True
    path = os.path.join(examples_dir(), spec.file)
    sys.path.insert(0, os.path.dirname(path))  # pdControl.py imports its neighbours
    sys.argv = [path]
    try:
        runpy.run_path(path, run_name="__main__")
        record.ended = "script end"
    except StepBudget:
        record.ended = "budget"
    if router is not None:
        _stats(record, router)


class Categories:
    """Where BoxCCD.step's time goes, by callee: every pybullet function the plugin calls
    (``_hooks.raw``) and every function of its C++ core module (``_core``), timed while the
    router is inside a BoxCCD step; the rest of the step is Python (and the C++ methods of
    the core's objects, which cannot be wrapped). Each wrapper costs ~0.2 us per call,
    included in its callee's time."""

    def __init__(self, router):
        from bullet_boxccd import _core
        from bullet_boxccd.pybullet_ccd import _hooks

        self.router, self.ns, self.calls = router, {}, {}
        self.now = [0, 0, 0]  # this step's ns in pybullet.stepSimulation, other pybullet functions, _core
        for space, prefix in ((_hooks.raw, "pybullet."), (_core, "_core.")):
            for name, fn in list(vars(space).items()):
                if callable(fn) and not isinstance(fn, type) and not name.startswith("_"):
                    setattr(space, name, self._timed(prefix + name, fn))

    def _timed(self, key, fn):
        ns, calls, router, clock, now = self.ns, self.calls, self.router, time.perf_counter_ns, self.now
        group = 0 if key == "pybullet.stepSimulation" else 1 if key.startswith("pybullet.") else 2

        def timed(*args, **kwargs):
            if not router.inside:
                return fn(*args, **kwargs)
            t0 = clock()
            try:
                return fn(*args, **kwargs)
            finally:
                dt = clock() - t0
                ns[key] = ns.get(key, 0) + dt
                calls[key] = calls.get(key, 0) + 1
                now[group] += dt
        return timed


def run(client, variant, steps=None, seed=0, profile=None, categories=False):
    spec = CLIENTS[client]
    steps = spec.steps if steps is None else steps
    record = Record(client, variant, seed, steps)
    if variant != "bare":
        import bullet_boxccd  # noqa: F401  (before pybullet and before any world is built)
    profiler = None
    if profile and variant == "ccd":
        import cProfile

        profiler = cProfile.Profile()
    if categories and variant == "ccd":
        _CATEGORIES.append(True)
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            if isinstance(spec, Env):
                run_env(record, spec, variant, steps, seed, profiler)
            else:
                run_script(record, spec, variant, steps, seed, profiler)
        except Exception:
            record.error = traceback.format_exc(limit=12)
    record.wall_s = time.perf_counter() - t0
    _warnings_into(record, caught)
    if profiler is not None:
        profiler.dump_stats(profile)
    return record


_CATEGORIES = []  # set by run(categories=True): the routers install a Categories


# ------------------------------------------------- the harness side
HERE = os.path.abspath(__file__)


def run_subprocess(client, variant, steps=None, seed=0, timeout=600, profile=None, workdir=None,
                   categories=False):
    """Run one variant in a fresh interpreter; the Record as a dict, with ``error`` set if the
    process failed (a signal such as SIGSEGV, a timeout, an exit without a record)."""
    import signal
    import subprocess

    work = workdir or tempfile.mkdtemp(prefix="boxccd_clients_")
    out = os.path.join(work, f"{client}.{variant}.{seed}.pkl")
    if os.path.exists(out):
        os.remove(out)
    cmd = [sys.executable, HERE, client, variant, "--seed", str(seed), "--out", out]
    if steps is not None:
        cmd += ["--steps", str(steps)]
    if profile:
        cmd += ["--profile", profile]
    if categories:
        cmd += ["--categories"]
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONHASHSEED="0")
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"client": client, "variant": variant, "seed": seed, "error": f"timeout after {timeout} s"}
    if proc.returncode != 0 or not os.path.exists(out):
        rc = proc.returncode
        why = f"killed by {signal.Signals(-rc).name}" if rc < 0 else f"exit code {rc}"
        return {"client": client, "variant": variant, "seed": seed,
                "error": f"{why}; stderr tail:\n{proc.stderr[-3000:]}"}
    with open(out, "rb") as f:
        rec = pickle.load(f)
    os.remove(out)
    return rec


def max_diff(a, b):
    """(max |a - b| over the aligned steps, first step index where they differ (None),
    steps compared). A step whose vectors differ in shape (a body more or less) counts as
    inf; so do steps one run took and the other did not."""
    worst, first = 0.0, None
    n = min(len(a), len(b))
    for i in range(n):
        x, y = np.asarray(a[i]), np.asarray(b[i])
        if x.shape != y.shape:
            e = np.inf
        elif x.size:
            with np.errstate(invalid="ignore"):
                d = np.abs(x - y)
            e = float(np.max(np.where(np.isnan(x) & np.isnan(y), 0.0, np.where(np.isnan(d), np.inf, d))))
        else:
            e = 0.0
        if e > 0 and first is None:
            first = i
        worst = max(worst, e)
    if len(a) != len(b):
        worst = np.inf
        first = n if first is None else first
    return worst, first, n


def compare(reference, other):
    """``other``'s trajectory against ``reference``'s (both Record dicts)."""
    obs = max_diff(reference.get("obs", []), other.get("obs", []))
    poses = max_diff(reference.get("poses", []), other.get("poses", []))
    return {"obs_diff": obs[0], "obs_first": obs[1], "pose_diff": poses[0], "pose_first": poses[1],
            "steps_compared": max(obs[2], poses[2])}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("client", choices=sorted(CLIENTS))
    ap.add_argument("variant", choices=VARIANTS)
    ap.add_argument("--steps", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", required=True)
    ap.add_argument("--profile", default=None, help="cProfile of the BoxCCD step calls (variant ccd)")
    ap.add_argument("--categories", action="store_true", help="time BoxCCD.step's pybullet and core calls")
    a = ap.parse_args(argv)
    out = os.path.abspath(a.out)
    profile = os.path.abspath(a.profile) if a.profile else None
    with tempfile.TemporaryDirectory() as work:  # scripts write logs into the working directory
        os.chdir(work)
        record = run(a.client, a.variant, a.steps, a.seed, profile, a.categories)
    with open(out, "wb") as f:
        pickle.dump(dict(record.__dict__), f)  # plain types only: readable without this module
    sys.stdout.flush()
    # Skip interpreter teardown: an env's __del__ disconnects clients in whatever order.
    os._exit(0)


if __name__ == "__main__":
    main()
