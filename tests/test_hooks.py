"""What BoxCCD learns of a pybullet world without pybullet's help, checked against pybullet.

* The journal's reading of every hooked call (``_hooks.SIGNATURES``): the table against
  pybullet's own argument parser, pybullet's docstrings, and real calls with two clients.
* MJCF bodies: their boxes read from the file, never with getCollisionShapeData (which
  kills the process on them), compared with getCollisionShapeData where it is safe, in
  subprocesses; every model of pybullet_data/mjcf and the gym Hopper and Ant.
* Maximal-coordinate bodies with links, heightfields, the import order of bullet_boxccd
  and pybullet, and where a BoxCCDWarning points.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import textwrap
import warnings

import numpy as np
import pybullet as p
import pybullet_data
import pytest
from capture import CFile

from bullet_boxccd import BoxCCD
from bullet_boxccd.pybullet_ccd import BoxCCDWarning, _hooks, mjcf

DT = 1 / 240
MJCF_DIR = os.path.join(pybullet_data.getDataPath(), "mjcf")
MJCF_FILES = sorted(f for f in os.listdir(MJCF_DIR) if f.endswith(".xml"))
ORIGINALS = p._bullet_boxccd_originals


def run_python(code, *args, timeout=300):
    """Run ``code`` in a fresh interpreter: (exit code, stdout, stderr)."""
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(code), *args], capture_output=True, text=True,
                       timeout=timeout, cwd=tempfile.gettempdir())
    return r.returncode, r.stdout, r.stderr


def reset(cid):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(DT, physicsClientId=cid)
    p.setGravity(0, 0, 0, physicsClientId=cid)


# --------------------------------------------------------------- signatures
def _error(f, *args, **kwargs):
    try:
        f(*args, **kwargs)
    except Exception as e:  # pybullet.error or TypeError: the message is what is checked
        return str(e)
    return None


def _parsable_values(f, n):
    """n values pybullet's parser converts for the first n parameters of f's last form,
    found without running f: an unknown keyword stops every call at the parser."""
    values = []
    for _ in range(n):
        for candidate in ([1.0], 1, "a"):  # a list first: no legacy form takes it
            m = _error(f, *values, candidate, __probe__=0) or ""
            if "invalid keyword" in m or "required argument" in m:
                values.append(candidate)
                break
        else:
            raise AssertionError(f"no value converts at position {len(values) + 1} of {f.__name__}: {m}")
    return values


@pytest.mark.parametrize("name", sorted(_hooks.SIGNATURES))
def test_signature_table_is_pybullets_own_parameter_list(name):
    """Every name of the form pybullet parses last, at its position, as pybullet's parser
    reports it: with all parameters but the client id given positionally, naming a
    parameter again is an error that states the name's position; one more positional
    argument states the count; and the client id is the last parameter."""
    f, form = ORIGINALS[name], _hooks.SIGNATURES[name][-1]
    assert form[-1] == "physicsClientId"
    values = _parsable_values(f, len(form) - 1)
    m = _error(f, *values, 99, 1)
    assert f"at most {len(form)} argument" in m, m
    for i, param in enumerate(form[:-1]):
        m = _error(f, *values, **{param: values[i]})
        assert f"given by name ('{param}') and position ({i + 1})" in (m or ""), (param, m)
    m = _error(f, *values, physicsClientId=99) or ""  # client 99 is not connected: nothing runs
    assert "invalid keyword" not in m and "given by name" not in m, m


def test_docstring_signatures_agree_with_the_table_or_pybullet_rejects_them():
    """Where pybullet's docstring gives a signature, its names are the table's, in the
    table's order, except where pybullet itself rejects the docstring's name (the
    docstring is wrong: resetJointState's "objectUniqueId") or the docstring leaves a
    parameter out (resetSimulation's "flags", before physicsClientId: a positional
    resetSimulation(1) is flags=1 on client 0, not client 1)."""
    checked, rejected, omitted = 0, set(), set()
    for name, forms in _hooks.SIGNATURES.items():
        doc = (ORIGINALS[name].__doc__ or "").strip()
        m = re.match(r"(?:\w+\s*=\s*)?" + name + r"\((.*?)\)", doc)
        if not m:
            continue
        checked += 1
        documented = [a.split("=")[0].strip() for a in m.group(1).split(",") if a.strip()]
        form = forms[-1]
        values = _parsable_values(ORIGINALS[name], len(form) - 1)
        known = [n for n in documented if n in form]
        assert known == [n for n in form if n in known], (name, documented, form)
        for i, n in enumerate(documented):
            if n not in form:
                msg = _error(ORIGINALS[name], *values, **{n: values[min(i, len(values) - 1)]}) or ""
                assert f"'{n}' is an invalid keyword" in msg, (name, n, msg)
                rejected.add((name, n))
        omitted |= {(name, n) for n in form if n not in documented and len(documented) < len(form)}
    assert checked >= 7
    assert ("resetJointState", "objectUniqueId") in rejected and ("resetSimulation", "flags") in omitted
    assert _hooks.bind("resetSimulation", (1,), {}) == {"flags": 1}


def _call_forms(form, values):
    """(args, kwargs) of every way to pass ``values`` (by name, in form order) to a form:
    k positional and the rest by keyword, for each k."""
    names = [n for n in form if n in values]
    assert names == list(form[:len(names)])
    return [(tuple(values[n] for n in names[:k]), {n: values[n] for n in names[k:]}) for k in range(len(names) + 1)]


@pytest.mark.parametrize("name", sorted(_hooks.SIGNATURES))
def test_every_call_form_binds_every_argument_to_its_name(name):
    """Positional, keyword, mixed, client id anywhere pybullet takes it: ``bind`` gives each
    argument its parameter's name, for every form of the table."""
    for form in _hooks.SIGNATURES[name]:
        values = {n: ("value", n) for n in form}
        if form.numbers:  # a legacy form is told apart by its numbers
            values = {n: (float(i) if n in form.numbers else "file.urdf") for i, n in enumerate(form)}
        for args, kwargs in _call_forms(form, values):
            bound = _hooks.bind(name, args, kwargs)
            expected = {_hooks._ALIASES.get(n, n): v for n, v in values.items()}
            assert bound == expected, (name, form, len(args))
        if "physicsClientId" in form:
            assert _hooks._cid(_hooks.bind(name, (), {"physicsClientId": 3})) == 3


TWO_CLIENTS = r'''
import os, sys
import numpy as np
import bullet_boxccd
import pybullet as p
import pybullet_data
from bullet_boxccd.pybullet_ccd import _hooks

c0, c1 = p.connect(p.DIRECT), p.connect(p.DIRECT)
assert (c0, c1) == (0, 1)
data = pybullet_data.getDataPath()
cube = os.path.join(data, "cube_small.urdf")
J = _hooks.journal


def bodies(c):
    return p.getNumBodies(physicsClientId=c)


# loadURDF(file, x, y, z) and (file, x, y, z, qx, qy, qz, qw): pybullet's legacy forms load
# into client 0 (they take no client id), at that pose, never with maximal coordinates.
q = p.getQuaternionFromEuler([0.3, 0.2, 0.1])
for args in [(cube, 1.0, 2.0, 3.0), (cube, 1.0, 2.0, 3.0) + tuple(q)]:
    before = bodies(c0), bodies(c1)
    b = p.loadURDF(*args)
    assert (bodies(c0), bodies(c1)) == (before[0] + 1, before[1]), args
    pos, orn = p.getBasePositionAndOrientation(b, physicsClientId=c0)
    assert np.allclose(pos, [1, 2, 3]) and np.allclose(orn, args[4:] if len(args) == 8 else [0, 0, 0, 1], atol=1e-6)
    assert b in J(c0).created and b not in J(c1).created and b not in J(c0).maximal, args
b = p.loadURDF(fileName=cube, startPosX=0.5, startPosY=0.0, startPosZ=0.2)
assert b in J(c0).created and np.allclose(p.getBasePositionAndOrientation(b)[0], [0.5, 0, 0.2])

# The main form, every way of giving the client id: into client 1, journaled for client 1.
forms = [((cube, [0, 0, 1], [0, 0, 0, 1], 0, 0, 0, 1.0, c1), {}),
         ((cube,), dict(basePosition=[0, 0, 1], physicsClientId=c1)),
         ((), dict(fileName=cube, useMaximalCoordinates=1, physicsClientId=c1)),
         ((cube, [0, 0, 1], [0, 0, 0, 1], 1), dict(physicsClientId=c1))]
for args, kwargs in forms:
    before = bodies(c0), bodies(c1)
    b = p.loadURDF(*args, **kwargs)
    assert (bodies(c0), bodies(c1)) == (before[0], before[1] + 1), (args, kwargs)
    assert b in J(c1).created
    maximal = kwargs.get("useMaximalCoordinates", args[3] if len(args) > 3 else 0)
    assert (b in J(c1).maximal) == bool(maximal), (args, kwargs)

# createMultiBody with the client id at its position (21st), and by keyword.
col = p.createCollisionShape(p.GEOM_BOX, 0.0, [0.1] * 3, physicsClientId=c1)
assert col in J(c1).shapes and J(c1).shapes[col][1]["halfExtents"] == [0.1] * 3
positional = (1.0, col, -1, [0, 0, 2], [0, 0, 0, 1], [0, 0, 0], [0, 0, 0, 1], [], [], [], [], [], [], [], [], [], [],
              1, 0)
before = bodies(c0), bodies(c1)
box = p.createMultiBody(*positional[:19], physicsClientId=c1)
assert (bodies(c0), bodies(c1)) == (before[0], before[1] + 1)
batch = p.createMultiBody(*positional[:19], [[0, 0, 2], [1, 0, 2]], c1)
assert bodies(c0) == before[0] and len(batch) == 2
assert box in J(c1).maximal and set(batch) <= set(J(c1).maximal) and box not in J(c0).created

# World changes on client 1, positional client ids: journaled for client 1 only.
other = p.loadURDF(cube, physicsClientId=c1)
serials = {c: (dict(J(c).pair_rules), dict(J(c).group_mask), dict(J(c).moved), J(c).params, J(c).stepped)
           for c in (c0, c1)}
p.setCollisionFilterPair(box, other, -1, -1, 0, c1)
p.setCollisionFilterGroupMask(other, -1, 3, 5, c1)
p.resetBasePositionAndOrientation(other, [1, 1, 1], [0, 0, 0, 1], c1)
p.resetBaseVelocity(other, [1, 0, 0], [0, 0, 0], c1)
p.setTimeStep(0.01, c1)
p.setGravity(0, 0, -1, c1)
p.stepSimulation(c1)
assert J(c1).pair_rules[_hooks.pair_rule_key(box, -1, other, -1)] is False
assert J(c1).group_mask[(other, -1)] == (3, 5)
assert other in J(c1).moved and other in J(c1).velocity_set
assert (dict(J(c0).pair_rules), dict(J(c0).group_mask), dict(J(c0).moved), J(c0).params, J(c0).stepped) == serials[c0]
assert J(c1).stepped > serials[c1][4] and J(c1).params > serials[c1][3]
p.changeDynamics(other, -1, 2.0, physicsClientId=c1)  # mass, positional
assert J(c1).bodies[other] > J(c1).bodies[box]
p.setPhysicsEngineParameter(0.01, 50, 1, -0.02, 3, physicsClientId=c1)
assert J(c1).num_substeps == 3 and J(c0).num_substeps == 0
p.setPhysicsEngineParameter(numSubSteps=0, physicsClientId=c1)

# The old keyword bodyIndex, and bodyUniqueId, of the motor functions.
arm = p.loadURDF(os.path.join(data, "kuka_iiwa", "model.urdf"), physicsClientId=c1)
p.setJointMotorControl2(bodyIndex=arm, jointIndex=0, controlMode=p.PD_CONTROL, physicsClientId=c1)
assert J(c1).pd_control and not J(c0).pd_control
J(c1).pd_control = False
p.setJointMotorControlArray(arm, [0, 1], p.PD_CONTROL, [0, 0], [0, 0], [10, 10], [0.1, 0.1], [1, 1], c1)
assert J(c1).pd_control and not J(c0).pd_control
p.setJointMotorControl2(bodyUniqueId=arm, jointIndex=0, controlMode=p.VELOCITY_CONTROL, physicsClientId=c1)
# Every argument positional: a torque is journaled (for the client named last), a position motor is not.
p.setJointMotorControl2(arm, 0, p.TORQUE_CONTROL, 0, 0, 5.0, 0.1, 1.0, 10, c1)
assert J(c1).impulses[-1][0] == "call" and J(c1).impulses[-1][1][1]["force"] == 5.0 and not J(c0).impulses
held = list(J(c1).impulses)
p.setJointMotorControl2(arm, 0, p.POSITION_CONTROL, 0.3, 0, 5.0, 0.1, 1.0, 10, c1)
p.setJointMotorControlArray(arm, [0, 1], controlMode=p.VELOCITY_CONTROL, targetVelocities=[1, 1], physicsClientId=c1)
assert J(c1).impulses == held and not J(c0).impulses

# loadSDF, loadMJCF and removeBody with the client id positional.
sdf = p.loadSDF(os.path.join(data, "stadium.sdf"), 0, 1.0, c1)
assert set(sdf) <= J(c1).created and not set(sdf) & J(c0).created - {0, 1, 2}
mj = p.loadMJCF(os.path.join(data, "mjcf", "hello_mjcf.xml"), 0, 1, c1)
assert all(b in J(c1).mjcf for b in mj) and not any(b in J(c0).mjcf for b in mj)
p.removeBody(mj[-1], c1)
assert mj[-1] not in J(c1).created and mj[-1] not in J(c1).mjcf
p.resetSimulation(0, c1)
assert not J(c1).created and J(c0).created
print("OK")
'''


def test_calls_with_two_clients_are_journaled_for_the_client_pybullet_used():
    code, out, err = run_python(TWO_CLIENTS)
    assert code == 0 and "OK" in out, err[-3000:]


# -------------------------------------------------------------------- MJCF
GUARDED_RUN = r'''
import os, sys, warnings
import bullet_boxccd
import pybullet as p
import pybullet_data
from bullet_boxccd import BoxCCD
from bullet_boxccd.pybullet_ccd import _hooks

real = _hooks.raw.getCollisionShapeData


def guarded(body, link, physicsClientId=0):
    if body in getattr(_hooks.journal(physicsClientId), "mjcf", ()):
        print(f"getCollisionShapeData called on MJCF body {body} link {link}", flush=True)
        os._exit(3)
    return real(body, link, physicsClientId=physicsClientId)


_hooks.raw.getCollisionShapeData = guarded
cid = p.connect(p.DIRECT)
p.setGravity(0, 0, -9.81, physicsClientId=cid)
p.loadURDF(os.path.join(pybullet_data.getDataPath(), "plane.urdf"), physicsClientId=cid)
ids = p.loadMJCF(sys.argv[1], physicsClientId=cid)
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    ccd = BoxCCD(cid)
    for _ in range(20):
        ccd.step()
print("OK", ccd.stats.tracked_boxes)
'''


@pytest.mark.parametrize("name", MJCF_FILES)
def test_every_pybullet_data_mjcf_model_steps_under_boxccd_without_a_crash(name):
    """pybullet's getCollisionShapeData kills the process on links of these models (a
    SIGSEGV: hopper link 3, ant link 0, ...): BoxCCD never calls it on an MJCF body."""
    code, out, err = run_python(GUARDED_RUN, os.path.join(MJCF_DIR, name))
    assert code == 0 and "OK" in out, (code, out[-2000:], err[-2000:])


UNSEEN_MJCF = r'''
import os, sys, warnings
import bullet_boxccd
import pybullet as p
import pybullet_data
from bullet_boxccd import BoxCCD, BoxCCDWarning

cid = p.connect(p.DIRECT)
# Loaded through pybullet's own function (as before bullet_boxccd was imported): the
# journal does not know the file; the importer's link and joint names give it away.
(body,) = p._bullet_boxccd_originals["loadMJCF"](os.path.join(pybullet_data.getDataPath(), "mjcf", sys.argv[1]))
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    ccd = BoxCCD(cid)
    ccd.step()
mine = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning) and "loadMJCF" in str(w.message)]
assert len(mine) == 1 and f"body {body}:" in mine[0], mine
print("OK")
'''


@pytest.mark.parametrize("name", ["hopper.xml", "ant.xml"])
def test_an_mjcf_body_made_unseen_is_recognised_and_not_asked_for_its_shapes(name):
    code, out, err = run_python(UNSEEN_MJCF, name)
    assert code == 0 and "OK" in out, (code, err[-2000:])


FEATURES_XML = """<mujoco model="features">
  <compiler angle="degree"/>
  <default>
    <geom contype="3" conaffinity="5"/>
    <default class="soft"><geom contype="0" conaffinity="2"/></default>
  </default>
  <worldbody>
    <geom name="floor" type="box" size="2 2 0.05" pos="0 0 -0.05" quat="0.9 0.1 0.2 0.3"/>
    <geom type="plane" size="1 1 0.1"/>
    <body name="free_box" pos="1 2 3" quat="0.5 0.5 0.5 0.5">
      <joint type="free"/>
      <inertial pos="0.01 0.02 0.03" quat="0.7 0.1 -0.2 0.3" mass="2" diaginertia="1 1 1"/>
      <geom type="box" size="0.1 0.2 0.3" pos="0.3 -0.2 0.1" quat="0.1 0.2 0.3 0.4"/>
      <geom type="box" size=".05 .06 .07" axisangle="1 1 0 0.7" euler="10 20 30"/>
      <geom type="sphere" size="0.05" pos="0 0 0.4"/>
    </body>
    <body pos="0 0 1" childclass="soft">
      <joint name="slide_x" type="slide" axis="1 0 0" pos="0.1 0 0"/>
      <joint type="hinge" axis="0 1 0" pos="0 0.2 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0.1" size="0.02"/>
      <geom type="box" size="0.11 0.12 0.13" pos="0.1 0.1 0.1" fromto="0 0 0 1 1 1" class="ignored"/>
      <body name="arm" pos="0.3 0 0">
        <joint type="hinge" axis="0 0 1" pos="0.05 0 0"/>
        <geom type="box" size="0.2 0.03 0.03" pos="0.2 0 0" contype="7"/>
        <geom type="cylinder" fromto="0 0 0 0.4 0 0" size="0.01"/>
        <inertial pos="0.1 0 0.05" mass="1" diaginertia="1 1 1"/>
        <body pos="0.4 0 0">
          <joint type="ball"/>
          <geom type="box" size="0.05 0.05 0.05"/>
        </body>
        <body name="hand" pos="0.4 0.1 0">
          <geom type="box" size="0.02 0.03 0.04" pos="0.01 0 0"/>
          <body name="finger">
            <joint type="slide" axis="1 0 0"/>
            <joint type="hinge" axis="0 0 1"/>
            <geom type="box" size="0.01 0.01 0.05" quat="1 0 0 1"/>
          </body>
        </body>
      </body>
      <body name="tail" pos="-0.3 0 0">
        <joint type="hinge" axis="0 0 1"/>
        <geom type="capsule" size="0.02 0.1"/>
        <geom type="box" size="0.03 0.03 0.03" pos="-0.1 0 0"/>
      </body>
    </body>
    <body name="static_shelf" pos="3 0 0">
      <geom type="box" size="0.5 0.1 0.02" pos="0 0 0.5"/>
    </body>
  </worldbody>
</mujoco>
"""

COMPARE = r'''
import json, sys
import numpy as np
import bullet_boxccd
import pybullet as p
from bullet_boxccd.pybullet_ccd import _hooks, mjcf

cid = p.connect(p.DIRECT)
rows = []
for arg in sys.argv[1:]:
    path, flags = arg.rsplit(":", 1)
    p.resetSimulation(physicsClientId=cid)
    ids = p.loadMJCF(path, flags=int(flags), physicsClientId=cid)
    mapping = mjcf.match(_hooks.raw, cid, _hooks.journal(cid).mjcf[ids[0]])
    for b in ids:
        model = mapping[b]
        assert not isinstance(model, str), (path, b, model)
        for i, lk in enumerate(model.links):
            if lk.multisphere:  # the shape getCollisionShapeData crashes on
                continue
            data = p.getCollisionShapeData(b, i - 1, physicsClientId=cid)
            theirs = [(0.5 * np.array(d[3]), np.array(d[5]), np.array(p.getMatrixFromQuaternion(d[6])).reshape(3, 3))
                      for d in data if d[2] == p.GEOM_BOX]  # pybullet's own frames: the reference, on purpose
            # a plane: its normal and origin, world-free (pybullet's normal is in its shape's frame)
            planes = [(np.array(p.getMatrixFromQuaternion(d[6])).reshape(3, 3) @ d[3], np.array(d[5]))
                      for d in data if d[2] == p.GEOM_PLANE]
            err = 0.0
            if len(theirs) == len(lk.boxes):
                for (h, X), (h2, t2, R2) in zip(lk.boxes, theirs):
                    err = max(err, np.abs(h - h2).max(), np.abs(X[:3, 3] - t2).max(), np.abs(X[:3, :3] - R2).max())
            if len(planes) == len(lk.planes):
                for X, (n2, t2) in zip(lk.planes, planes):
                    err = max(err, np.abs(X[:3, 2] - n2).max(), np.abs(X[:3, 3] - t2).max())
            rows.append(dict(file=path, flags=int(flags), body=b, link=i - 1, name=lk.name,
                             ours=[len(lk.boxes), len(lk.planes)], theirs=[len(theirs), len(planes)], err=err,
                             others=[len(lk.others), len(data) - len(theirs) - len(planes)]))
print("\nRESULT " + json.dumps(rows))
'''


def test_mjcf_boxes_are_pybullets_own_boxes(tmp_path):
    """The boxes and planes read from the file, on every link of every model (pybullet_data/mjcf and a
    file with every feature the reader follows: nested bodies, joints that add links or
    drop them, inertial frames and fromto shifts, quat / axisangle (euler and a box's
    fromto ignored, as pybullet does), default classes, root-level geoms, and
    URDF_MAINTAIN_LINK_ORDER), equal pybullet's getCollisionShapeData to 1e-12, in a
    subprocess, on the links where that call is safe."""
    features = tmp_path / "features.xml"
    features.write_text(FEATURES_XML)
    implicit, ordered = p.URDF_USE_IMPLICIT_CYLINDER, p.URDF_MAINTAIN_LINK_ORDER
    args = [f"{features}:{fl}" for fl in (0, implicit, implicit | ordered)]
    args += [f"{os.path.join(MJCF_DIR, f)}:{fl}" for f in MJCF_FILES for fl in (0, ordered)]
    code, out, err = run_python(COMPARE, *args)
    assert code == 0, (code, err[-3000:])
    rows = json.loads(re.search(r"^RESULT (.*)$", out, re.M).group(1))
    for r in rows:
        assert r["ours"] == r["theirs"] and r["err"] <= 1e-12 and r["others"][0] == r["others"][1], r
    mine = [r for r in rows if r["file"] == str(features)]
    # 9 boxes in pybullet's bodies (the ball joint's is not); with flags 0 the link with a
    # fromto capsule is not asked (it would crash), so 8 are compared there.
    boxes = [sum(r["ours"][0] for r in mine if r["flags"] == fl) for fl in (0, implicit, implicit | ordered)]
    assert boxes == [8, 9, 9]
    assert sum(r["ours"][0] for r in rows) > 30 and sum(r["ours"][1] for r in rows) > 5  # boxes; planes


def test_mjcf_groups_and_masks_are_pybullets():
    """A link's contype / conaffinity (its last geom's, or its class's) as the file sets
    them; defaults 1 / 1."""
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "f.xml")
        with open(path, "w") as f:
            f.write(FEATURES_XML)
        models = [m for m in mjcf.read_models(path) if m is not None]
    groups = {lk.name: lk.group_mask for m in models for lk in m.links if lk.group_mask}
    assert groups["floor"] == (3, 5) and groups["free_box"] == (3, 5)
    assert groups["link3_0"] == (0, 2) and groups["arm"] == (0, 2) and groups["hand"] == (0, 2)
    mixed = models[3].links[[lk.name for lk in models[3].links].index("arm")]
    assert len(mixed.boxes) == 1 and mixed.others == ["cylinder"]


MJCF_CUBE = """<mujoco><worldbody>
<body name="cube" pos="{x} 0.1 0.05">
  <joint type="free"/>
  <inertial pos="0.01 0.02 0" mass="1" diaginertia="0.002 0.002 0.002"/>
  <geom type="box" size="0.05 0.05 0.05" pos="0.02 -0.01 0" quat="0.99 0 0 0.1" {filters}/>
</body></worldbody></mujoco>"""


def mjcf_cube_through_wall(cid, use, phase, filters, tmp_path):
    reset(cid)
    p.createMultiBody(0, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.0005, 1, 1], physicsClientId=cid),
                      physicsClientId=cid)
    path = tmp_path / f"cube_{phase:.3f}_{len(filters)}.xml"
    path.write_text(MJCF_CUBE.format(x=-0.3 - phase * 100 * DT, filters=filters))
    (cube,) = p.loadMJCF(str(path), physicsClientId=cid)
    p.changeDynamics(cube, -1, linearDamping=0, angularDamping=0, maxJointVelocity=10000, physicsClientId=cid)
    p.resetBaseVelocity(cube, [100, 0, 0], [3, -2, 5], physicsClientId=cid)
    ccd = BoxCCD(cid) if use else None
    for _ in range(40):
        ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
    return p.getBasePositionAndOrientation(cube, physicsClientId=cid)[0][0] > 0.0


def test_an_mjcf_box_is_swept_where_pybullet_has_it_and_its_filters_mirrored(cid, tmp_path):
    """A cube from an MJCF file (box offset in its body, inertial frame offset) thrown at a
    1 mm wall at 100 m/s: plain pybullet lets it through, BoxCCD never; with contype 0 /
    conaffinity 0 pybullet collides it with nothing, and BoxCCD lets it through too."""
    phases = np.linspace(0, 1, 6, endpoint=False)
    plain = sum(mjcf_cube_through_wall(cid, False, ph, "", tmp_path) for ph in phases)
    swept = sum(mjcf_cube_through_wall(cid, True, ph, "", tmp_path) for ph in phases)
    assert swept == 0 and plain >= 3, (swept, plain)
    off = 'contype="0" conaffinity="0"'
    assert all(mjcf_cube_through_wall(cid, use, ph, off, tmp_path) for use in (False, True) for ph in phases[:2])


def test_an_mjcf_body_that_cannot_be_mapped_is_named_in_one_warning(cid, tmp_path, monkeypatch):
    """The file changed since it was loaded: its links no longer match the body's. One
    BoxCCDWarning names the body and the boxes left out; summary() says so; and
    getCollisionShapeData is not called on it."""
    reset(cid)
    path = tmp_path / "changed.xml"
    path.write_text(MJCF_CUBE.format(x=0, filters=""))
    (cube,) = p.loadMJCF(str(path), physicsClientId=cid)
    path.write_text(MJCF_CUBE.format(x=0, filters="").replace('name="cube"', 'name="renamed"'))
    called = []
    real = _hooks.raw.getCollisionShapeData
    monkeypatch.setattr(_hooks.raw, "getCollisionShapeData", lambda b, *a, **k: called.append(b) or real(b, *a, **k))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ccd = BoxCCD(cid)
        ccd.step()
        ccd.step()
    mine = [w for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert len(mine) == 1 and f"body {cube}:" in str(mine[0].message) and "its file has 1" in str(mine[0].message)
    assert cube not in called
    assert "not tracked: body" in ccd.summary() and ccd.stats.tracked_boxes == 0


def test_an_mjcf_body_loaded_without_multibody_keeps_only_its_root(cid, tmp_path):
    """loadMJCF(useMultiBody=0): pybullet keeps the root as the body (links it does not
    pose): the root's box is tracked, the others are named in one warning."""
    reset(cid)
    path = tmp_path / "two.xml"
    path.write_text("""<mujoco><worldbody><body name="root" pos="0 0 1"><joint type="free"/>
        <geom type="box" size="0.1 0.1 0.1"/>
        <body name="child" pos="0.5 0 0"><joint type="hinge" axis="0 0 1"/><geom type="box" size="0.1 0.2 0.1"/></body>
        </body></worldbody></mujoco>""")
    (body,) = p.loadMJCF(str(path), useMultiBody=0, physicsClientId=cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ccd = BoxCCD(cid)
    mine = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert len(mine) == 1 and f"body {body}: 1 box on link 1 (1)" in mine[0], mine
    assert ccd.stats.tracked_boxes == 1
    lo, hi = p.getAABB(body, -1, physicsClientId=cid)
    t = ccd.world.tables
    assert np.allclose(t.half[0], [0.1, 0.1, 0.1]) and np.allclose(np.add(lo, hi) / 2, [0, 0, 1], atol=1e-6)


GYM = r'''
import sys
try:
    import gym
    import pybullet_envs  # noqa: F401
except ImportError as e:
    print("SKIP", e)
    sys.exit(77)
import warnings
from bullet_boxccd import BoxCCD

env = gym.make(sys.argv[1])
env.reset()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    ccd = BoxCCD(env.unwrapped._p._client)
    robot = env.unwrapped.robot
    for _ in range(20):
        robot.apply_action(env.action_space.sample())
        ccd.step()
    env.step(env.action_space.sample())
    ccd.step()
print("OK")
'''


@pytest.mark.parametrize("env", ["HopperBulletEnv-v0", "AntBulletEnv-v0"])
def test_gym_hopper_and_ant_step_under_boxccd(env):
    """pybullet_envs' MJCF robots (gym 0.23.1), built and stepped by BoxCCD."""
    code, out, err = run_python(GYM, env)
    if code == 77:
        pytest.skip(out.strip())
    assert code == 0 and "OK" in out, (code, out[-2000:], err[-2000:])


# ------------------------------------------------- maximal bodies with links
def snake(cid, n=3):
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.2, 0.1, 0.05], physicsClientId=cid)
    return p.createMultiBody(1, col, -1, [0, 0, 1], [0, 0, 0, 1], linkMasses=[1] * n,
                             linkCollisionShapeIndices=[col] * n, linkVisualShapeIndices=[-1] * n,
                             linkPositions=[[0.45, 0, 0]] * n, linkOrientations=[[0, 0, 0, 1]] * n,
                             linkInertialFramePositions=[[0, 0, 0]] * n,
                             linkInertialFrameOrientations=[[0, 0, 0, 1]] * n, linkParentIndices=list(range(n)),
                             linkJointTypes=[p.JOINT_REVOLUTE] * n, linkJointAxis=[[0, 0, 1]] * n,
                             useMaximalCoordinates=True, physicsClientId=cid)


def test_a_maximal_body_with_links_names_the_boxes_it_leaves_out(cid):
    """createMultiBody(..., link*, useMaximalCoordinates=True), as snake.py does: pybullet
    reports 0 joints and poses none of the links (getLinkState gives None, getAABB fails,
    contacts and ray hits name body -1): the base is tracked, the links' boxes are named
    in one warning and in summary(), and not again when the world changes later (a body
    made beside it)."""
    reset(cid)
    b = snake(cid)
    assert p.getNumJoints(b, physicsClientId=cid) == 0
    assert p.getLinkState(b, 0, physicsClientId=cid) is None
    with pytest.raises(p.error):
        p.getAABB(b, 0, physicsClientId=cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ccd = BoxCCD(cid)
        ccd.step()
        p.createMultiBody(1, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid),
                          basePosition=[3, 0, 1], physicsClientId=cid)
        ccd.step()
    mine = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert len(mine) == 1 and f"body {b}: 3 boxes on links 0 (1), 1 (1), 2 (1)" in mine[0], mine
    assert ccd.stats.tracked_boxes == 2  # the snake's base and the cube
    assert f"not tracked: body {b}: 3 boxes" in ccd.summary()


# ------------------------------------------------------------- heightfields
def test_a_heightfield_is_left_to_pybullet_without_its_error_print(cid):
    """pybullet prints "Unexpected collision shape type" when a heightfield's shape is
    read: the journal knows the shape's type, and BoxCCD does not ask."""
    reset(cid)
    rows = cols = 16
    hf = p.createCollisionShape(p.GEOM_HEIGHTFIELD, meshScale=[0.1, 0.1, 1], heightfieldTextureScaling=8,
                                heightfieldData=[0.0] * (rows * cols), numHeightfieldRows=rows,
                                numHeightfieldColumns=cols, physicsClientId=cid)
    ground = p.createMultiBody(0, hf, physicsClientId=cid)
    p.createMultiBody(1, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid),
                      basePosition=[0, 0, 1], physicsClientId=cid)
    with CFile() as out:
        ccd = BoxCCD(cid)
        ccd.step()
    assert "Unexpected collision shape type" not in out.text, out.text
    assert f"body {ground} link -1: heightfield" in ccd.summary() and ccd.stats.tracked_boxes == 1


# ------------------------------------------------------------- import order
IMPORT_ORDER = r'''
import sys, warnings
if sys.argv[1] == "bullet_boxccd first":
    import bullet_boxccd
    assert "pybullet" not in sys.modules and "bullet_boxccd.pybullet_ccd" not in sys.modules
    import pybullet as p
else:
    import pybullet as p
    import bullet_boxccd
assert hasattr(p, "_bullet_boxccd_originals")
cid = p.connect(p.DIRECT)
p.setTimeStep(1 / 240)
wall = p.createMultiBody(0, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.0005, 1, 1]))
cube = p.createMultiBody(1, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3), basePosition=[-0.3, 0.1, 0.05])
p.setCollisionFilterPair(wall, cube, -1, -1, 0)
p.resetBaseVelocity(cube, [100, 0, 0], [0, 0, 0])
with warnings.catch_warnings():
    warnings.simplefilter("error")
    ccd = bullet_boxccd.BoxCCD(cid)
    for _ in range(30):
        ccd.step()
assert p.getBasePositionAndOrientation(cube)[0][0] > 1.0, "the filtered wall stopped the cube"
print("OK")
'''


@pytest.mark.parametrize("order", ["bullet_boxccd first", "pybullet first"])
def test_the_world_is_journaled_whichever_is_imported_first(order):
    """A world built with pybullet's own setCollisionFilterPair after either import order:
    BoxCCD sees the filter (the cube passes the filtered wall, as in pybullet) and warns
    of nothing; importing bullet_boxccd alone does not import pybullet."""
    code, out, err = run_python(IMPORT_ORDER, order)
    assert code == 0 and "OK" in out, err[-3000:]


# ------------------------------------------------------------ warning lines
def test_a_boxccd_warning_points_at_the_users_line(cid):
    """Warnings raised while BoxCCD is built and while it steps name this file."""
    reset(cid)
    p.createMultiBody(1, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid),
                      physicsClientId=cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ccd = BoxCCD(cid, sweep_threshold=2.0)
        snake(cid)
        ccd.step()
    mine = [w for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert len(mine) == 2
    assert all(os.path.samefile(w.filename, __file__) for w in mine), [(w.filename, w.lineno) for w in mine]


def test_a_time_step_set_again_alike_is_no_change_of_the_world():
    """A script that sets its time step (or gravity) every step, to the same value, keeps
    BoxCCD's steps quiet; a new value, by either call, is a change."""
    import pybullet as p

    from bullet_boxccd.pybullet_ccd import _hooks

    cid = p.connect(p.DIRECT)
    try:
        j = _hooks.journal(cid)
        p.setTimeStep(0.01, physicsClientId=cid)
        p.setGravity(0, 0, -10, physicsClientId=cid)
        seen = j.params
        for _ in range(3):
            p.setTimeStep(0.01, physicsClientId=cid)
            p.setPhysicsEngineParameter(fixedTimeStep=0.01, physicsClientId=cid)
            p.setGravity(0, 0, -10, physicsClientId=cid)
        assert j.params == seen
        p.setPhysicsEngineParameter(fixedTimeStep=0.02, physicsClientId=cid)
        assert j.params > seen
        seen = j.params
        p.setTimeStep(0.01, physicsClientId=cid)  # back to 0.01 through the other call: a change
        assert j.params > seen
        seen = j.params
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        assert j.params > seen
        assert p.getPhysicsEngineParameters(physicsClientId=cid)["fixedTimeStep"] == 0.01
    finally:
        p.disconnect(cid)


def test_position_motors_are_the_latest_one_degree_position_commands_of_bodies_still_there():
    """What partial steps give again: each joint's latest command where it is a position
    motor given through setJointMotorControl2 or setJointMotorControlArray, in every call
    form; a velocity command after it, or a removal of its body, drops it."""
    cid = p.connect(p.DIRECT)
    try:
        kuka = os.path.join(pybullet_data.getDataPath(), "kuka_iiwa", "model.urdf")
        arm = p.loadURDF(kuka, useFixedBase=True, physicsClientId=cid)
        other = p.loadURDF(kuka, [2, 0, 0], useFixedBase=True, physicsClientId=cid)
        p.setJointMotorControlArray(arm, range(7), p.POSITION_CONTROL, [0.1] * 7, forces=[50] * 7,
                                    physicsClientId=cid)
        p.setJointMotorControl2(arm, 2, p.POSITION_CONTROL, 0.3, 0.0, 80, 0.5, physicsClientId=cid)
        p.setJointMotorControl2(bodyIndex=arm, jointIndex=4, controlMode=p.VELOCITY_CONTROL, targetVelocity=1.0,
                                physicsClientId=cid)
        p.setJointMotorControlArray(other, [0, 1], p.POSITION_CONTROL, targetPositions=[0.2, 0.2], physicsClientId=cid)
        motors = _hooks.position_motors(cid)
        assert motors[arm, 0] == {"targetPosition": 0.1, "force": 50.0}
        assert motors[arm, 2] == {"targetPosition": 0.3, "targetVelocity": 0.0, "force": 80.0, "positionGain": 0.5}
        assert (arm, 4) not in motors and (other, 0) in motors
        p.removeBody(other, physicsClientId=cid)
        assert sorted(_hooks.position_motors(cid)) == [(arm, j) for j in (0, 1, 2, 3, 5, 6)]
    finally:
        p.disconnect(cid)
