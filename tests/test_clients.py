"""Real clients: pybullet's own gym envs and example scripts, run unedited with every
``stepSimulation`` routed through ``BoxCCD.step()`` (benchmarks/_clients_run.py; the full
run with timings is benchmarks/clients.py).

Per client, a short horizon and one seed, each variant in its own interpreter (a crash is
a failure here, not a dead pytest): pybullet alone (``bare``, bullet_boxccd never
imported) and BoxCCD (``ccd``). Asserted: no crash or error; no BoxCCDWarning but the
ones named in ``TRUE_WARNINGS`` (each checked to be true, the reason given); no call of
the router from inside BoxCCD.step (it steps through pybullet's originals); the BoxCCD
was made for the env's own client (a BulletClient env runs on client 1, beside an empty
world on client 0); and a trajectory bit-identical to pybullet's alone: to the end (none of
these clients tunnels in its first steps, so BoxCCD has nothing to change), or, in those
named in ``ACTS`` with the reason, up to the first contact BoxCCD takes back. If it is not,
the bare run is repeated: a client that is not deterministic is named as such.
"""

import os
import sys

import pytest

pytest.importorskip("gym", reason="gym is not installed (pip install gym==0.23.1)")
pytest.importorskip("pybullet_envs", reason="pybullet_envs is not importable")

BENCH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "benchmarks")
sys.path.insert(0, BENCH)

from _clients_run import CLIENTS, Env, compare, run_subprocess  # noqa: E402

# Horizons (env steps; script: steps): the whole file runs in about a minute on 2 cores.
STEPS = {
    "CartPoleBulletEnv-v1": 200,  # two episodes at least: a done and a reset under BoxCCD
    "KukaBulletEnv-v0": 150,
    "RacecarBulletEnv-v0": 4,  # 50 stepSimulation calls per env step, and a reset's 100
    "MinitaurBulletEnv-v0": 100,  # 5 stepSimulation calls per env step
    "HopperBulletEnv-v0": 150,  # the MJCF robots: numSubSteps 4, taken by BoxCCD itself
    "AntBulletEnv-v0": 100,
    "Walker2DBulletEnv-v0": 100,
    "HalfCheetahBulletEnv-v0": 100,
    "HumanoidBulletEnv-v0": 60,
    "createObstacleCourse.py": 150,
    "snake.py": 150,
    "pdControl.py": 150,
    "switchConstraintSolver.py": 150,
    "video_sync_mp4.py": 150,
    "createMultiBodyBatch.py": 5,  # 10240 boxes: BoxCCD() reads them for ~2 s
    "humanoidMotionCapture.py": 60,
    "deformable_anchor.py": 40,
    "getClosestPoints.py": 40,
}

# BoxCCDWarnings that are true, by client: (a piece of the message, why it is true).
TRUE_WARNINGS = {
    "snake.py": [(
        "36 boxes on links 0 (1), 1 (1)",
        "snake.py builds its 36-link box chain with useMaximalCoordinates=True: pybullet then reports 0 joints "
        "and no link state (tests/test_hooks.py::test_a_maximal_body_with_links_names_the_boxes_it_leaves_out "
        "checks it against pybullet), so those boxes cannot be swept and are left to pybullet, as the warning "
        "says; the base box is tracked"), (
        "is not taken back with the world",
        "the snake's base box lands on the GEOM_PLANE ground at 3.9 m/s and BoxCCD takes the world back to the "
        "touch (ACTS); the maximal-coordinate links, whose state pybullet does not give, stay where the step left "
        "them, as the warning says")],
    "pdControl.py": [(
        "joint 1 moves at 100 (rad/s, m/s), pybullet's default joint velocity clamp",
        "pdControl.py's cartpoles (default maxJointVelocity) swing their poles, driven by its PD plugin, up to "
        "pybullet's joint velocity clamp: getJointState reads exactly 100.0 rad/s for joint 1, the value pybullet "
        "cuts a faster joint to, as the warning says")],
}


# Clients in whose first steps BoxCCD takes a contact back, and why that is what it is for: their
# trajectories are pybullet's alone, bit for bit, up to that step.
ACTS = {
    "snake.py": "its base box, a 0.5 m cube, drops 0.75 m onto the GEOM_PLANE ground and lands at 3.9 m/s: 1.6 cm "
                "a step, more than the 1 cm a box may move unswept, ending the step deeper than depth_tolerance "
                "(1 mm): BoxCCD resolves the landing from its touch, as on a box ground",
}


def test_every_client_has_a_horizon():
    assert set(STEPS) == set(CLIENTS)


@pytest.mark.parametrize("client", list(CLIENTS))
def test_client_under_boxccd(client, tmp_path):
    steps = STEPS[client]
    bare = run_subprocess(client, "bare", steps, 0, timeout=300, workdir=str(tmp_path))
    assert not bare.get("error"), f"{client} fails in pybullet alone:\n{bare['error']}"
    ccd = run_subprocess(client, "ccd", steps, 0, timeout=300, workdir=str(tmp_path))
    assert not ccd.get("error"), f"{client} fails under BoxCCD:\n{ccd['error']}"
    assert ccd["ccd_inner"] == 0, "BoxCCD.step called the routed stepSimulation (recursion)"
    assert ccd["env_steps"] == bare["env_steps"] > 0

    spec = CLIENTS[client]
    steps_the_world = isinstance(spec, Env) or spec.tick == "stepSimulation"
    if steps_the_world:
        assert ccd["sim_steps"] > 0, "no stepSimulation call reached BoxCCD"
        own = 1 if isinstance(spec, Env) and not spec.module_client else 0
        assert set(ccd["stats"]) == {own}, f"BoxCCDs made for clients {sorted(ccd['stats'])}, not {own}"

    allowed = TRUE_WARNINGS.get(client, [])
    unexpected = [m for m, _ in ccd["boxccd_warnings"] if not any(piece in m for piece, _ in allowed)]
    assert not unexpected, f"{client}: BoxCCDWarnings not known to be true: {unexpected}"
    for piece, _ in allowed:  # each listed warning is given (else the list is stale)
        assert any(piece in m for m, _ in ccd["boxccd_warnings"]), f"{client}: expected warning {piece!r}"
    assert not ccd["other_warnings"], ccd["other_warnings"]

    d = compare(bare, ccd)
    acted = ccd["first_act"]
    assert (acted >= 0) == (client in ACTS), f"{client}: BoxCCD took a contact back first at {acted} (-1: never)"
    if acted >= 0:  # pybullet's alone up to the step it took back
        assert all(first is None or first >= acted for first in (d["obs_first"], d["pose_first"])), (d, acted)
    elif d["obs_diff"] or d["pose_diff"]:
        again = run_subprocess(client, "bare", steps, 0, timeout=300, workdir=str(tmp_path))
        e = compare(bare, again)
        deterministic = not again.get("error") and e["obs_diff"] == 0 and e["pose_diff"] == 0
        stats = {c: {k: v for k, v in s.items() if k in ("rewinds", "partial_steps", "contacts", "swept_boxes")}
                 for c, s in ccd["stats"].items()}
        pytest.fail(f"{client}: BoxCCD's trajectory differs from pybullet's alone: max |obs diff| "
                    f"{d['obs_diff']:g} (first at step {d['obs_first']}), max |pose diff| {d['pose_diff']:g} "
                    f"(first at step {d['pose_first']}); stats {stats}; pybullet alone is "
                    f"{'deterministic' if deterministic else 'NOT deterministic'} here")
