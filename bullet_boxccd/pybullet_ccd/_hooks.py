"""What pybullet cannot be asked, recorded as it happens: a journal of world changes.

pybullet has no getter for collision filters, no event for a removed, re-created or
re-massed body, no record of a user's teleport of a static body, and reading its
time step costs a dictionary. So when this package is imported, the pybullet
functions that change those (``WRAPPED``) are replaced on the ``pybullet`` module by
wrappers that call pybullet's own function first (its arguments, errors and return
values are unchanged) and then note what changed in the ``Journal`` of the physics
client. The wrappers are builtins (``_core.as_builtin``): pybullet_utils'
``BulletClient`` passes its client id only to builtins.

The plugin itself calls pybullet's originals (``raw``): its own rewinds and partial
steps are not user changes.

Limits (BoxCCD warns where it meets them): calls made through references to
pybullet's functions taken before this package was imported (``from pybullet import
setCollisionFilterPair`` first) are not seen, nor changes made by another process
connected to the same server.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from types import SimpleNamespace

import pybullet

from .. import _core

__all__ = ["Journal", "journal", "raw", "install", "new_serial", "last_serial", "replay_impulses", "WRAPPED",
           "OR_MODE"]

# pybullet's defaults (PhysicsServerCommandProcessor): collisionFilterMode 1 ("group A
# & mask B, OR group B & mask A"); a new world starts with it.
OR_MODE = 1
# setJointMotorControl* modes whose torques pybullet computes once per stepSimulation
# (PD_CONTROL, STABLE_PD_CONTROL): not reproducible per substep.
_PD_MODES = {pybullet.PD_CONTROL, pybullet.STABLE_PD_CONTROL}

class _Serials:
    """One order over every client's events: each change of a world takes the next
    number, and ``last`` is the latest (a step that sees it unchanged needs no other
    check of the journals)."""

    def __init__(self):
        self.last = 0

    def __next__(self):
        self.last += 1
        return self.last


_serial = _Serials()


def new_serial() -> int:
    """A serial number later than every event so far."""
    return next(_serial)


def last_serial() -> int:
    """The latest serial number given (no event since a step that saw it)."""
    return _serial.last


@dataclass
class Journal:
    """What happened to one physics client through pybullet's own functions.

    ``serial``-valued fields hold the serial number of the latest such event (0: none);
    a BoxCCD compares them with the serial it last consumed.
    """

    reset: int = 0  # resetSimulation (everything below is cleared with it)
    bodies: dict = field(default_factory=dict)  # body -> serial of its creation, removal, mass or scale change
    last_body: int = 0  # the latest serial in ``bodies``
    created: set = field(default_factory=set)  # bodies made through the wrapped functions (provenance)
    params: int = 0  # fixedTimeStep / numSubSteps / gravity changed
    num_substeps: int = 0  # as last set through setPhysicsEngineParameter (0: never set)
    # Collision filters, as pybullet's collision filter plugin keeps them.
    pair_rules: dict = field(default_factory=dict)  # (body, link, body, link) in pybullet's key order -> enable
    group_mask: dict = field(default_factory=dict)  # (body, link) -> (group, mask) set by the user
    file_group_mask: dict = field(default_factory=dict)  # body -> {link name: (group, mask)} from a URDF
    filters_unknown: dict = field(default_factory=dict)  # body -> why its file's groups could not be read
    filter_mode: int = OR_MODE
    filters: int = 0
    # Teleports: body -> serial of the user's latest pose reset (base or joints).
    moved: dict = field(default_factory=dict)
    velocity_set: dict = field(default_factory=dict)  # body -> serial of the user's latest resetBaseVelocity
    restored: int = 0  # restoreState: every body jumped
    last_move: int = 0  # the latest of the three above
    stepped: int = 0  # the user called stepSimulation directly
    # Per-step impulses pybullet clears after every stepSimulation: replayed before each
    # substep when BoxCCD runs a world's substeps itself. (name, args) for raw calls.
    impulses: list = field(default_factory=list)
    pd_control: bool = False
    search_paths: list = field(default_factory=list)
    # How to build again what pybullet will not describe: collision shape index ->
    # (function, kwargs) that made it, and maximal-coordinate body -> (function, kwargs,
    # index of the body in the function's result). See shapes.Shadow.
    shapes: dict = field(default_factory=dict)
    maximal: dict = field(default_factory=dict)
    # Body -> the URDF_USE_SELF_COLLISION* bits it was loaded with (loadURDF, loadMJCF,
    # createMultiBody flags): whether, and which, of its links collide with each other.
    self_collision: dict = field(default_factory=dict)

    def clear(self):
        fresh = Journal()
        fresh.search_paths = self.search_paths  # a client setting, not a world one
        self.__dict__.update(fresh.__dict__)
        self.reset = next(_serial)


_journals: dict = {}


def journal(cid: int) -> Journal:
    """The journal of physics client ``cid`` (created empty on first use)."""
    j = _journals.get(cid)
    if j is None:
        j = _journals[cid] = Journal()
    return j


def pair_rule_key(body_a, link_a, body_b, link_b):
    """pybullet's key order for a pair filter (collisionFilterPlugin)."""
    if body_a > body_b or (body_a == body_b and link_a > link_b):
        return body_b, link_b, body_a, link_a
    return body_a, link_a, body_b, link_b


# --------------------------------------------------------------- arguments
def _arg(args, kwargs, i, name, default=None):
    """Argument ``name`` at position ``i`` as pybullet parses it."""
    return args[i] if len(args) > i else kwargs.get(name, default)


def _cid(args, kwargs, i):
    return int(_arg(args, kwargs, i, "physicsClientId", 0))


def _named(names, args, kwargs):
    """The call's arguments by name (pybullet's keyword names), without the client id."""
    out = dict(zip(names, args))
    out.update(kwargs)
    out.pop("physicsClientId", None)
    return out


_CREATE_SHAPE = ("shapeType", "radius", "halfExtents", "height", "fileName", "meshScale", "planeNormal", "flags",
                 "collisionFramePosition", "collisionFrameOrientation", "vertices", "indices",
                 "heightfieldTextureScaling", "heightfieldData", "numHeightfieldRows", "numHeightfieldColumns",
                 "replaceHeightfieldIndex")
_CREATE_SHAPES = ("shapeTypes", "radii", "halfExtents", "lengths", "fileNames", "meshScales", "planeNormals", "flags",
                  "collisionFramePositions", "collisionFrameOrientations")
_CREATE_BODY = ("baseMass", "baseCollisionShapeIndex", "baseVisualShapeIndex", "basePosition", "baseOrientation",
                "baseInertialFramePosition", "baseInertialFrameOrientation", "linkMasses",
                "linkCollisionShapeIndices", "linkVisualShapeIndices", "linkPositions", "linkOrientations",
                "linkInertialFramePositions", "linkInertialFrameOrientations", "linkParentIndices", "linkJointTypes",
                "linkJointAxis", "useMaximalCoordinates", "flags", "batchPositions")
_LOAD_URDF = ("fileName", "basePosition", "baseOrientation", "useMaximalCoordinates", "useFixedBase", "flags",
              "globalScaling")
_LOAD_SDF = ("sdfFileName", "useMaximalCoordinates", "globalScaling")


# ------------------------------------------------------------------ events
def _structure(cid, body):
    j = journal(cid)
    j.bodies[int(body)] = j.last_body = next(_serial)
    return j


def _on_create(cid, result):
    j = journal(cid)
    ids = result if isinstance(result, (tuple, list)) else (result,)
    s = j.last_body = next(_serial)
    for b in ids:
        if isinstance(b, int) and b >= 0:
            j.bodies[b] = s
            j.created.add(b)
            j.group_mask = {k: v for k, v in j.group_mask.items() if k[0] != b}
    return j


def _remove_body(args, kwargs, result):
    cid, b = _cid(args, kwargs, 1), int(_arg(args, kwargs, 0, "bodyUniqueId"))
    j = _structure(cid, b)
    j.created.discard(b)
    j.group_mask = {k: v for k, v in j.group_mask.items() if k[0] != b}  # they lived on its broadphase proxies
    j.file_group_mask.pop(b, None)
    j.filters_unknown.pop(b, None)
    j.maximal.pop(b, None)
    j.filters = next(_serial)  # pair rules stay: pybullet keys them by id, and a new body may reuse it


def _reset_simulation(args, kwargs, result):
    journal(_cid(args, kwargs, 1)).clear()


def _note_maximal(j, name, named, result, flag="useMaximalCoordinates"):
    if int(named.get(flag, 0) or 0) > 0:
        ids = result if isinstance(result, (tuple, list)) else (result,)
        for i, b in enumerate(ids):
            j.maximal[b] = (name, named, i)


def _create_shape(name, names, i_cid):
    def on(args, kwargs, result):
        journal(_cid(args, kwargs, i_cid)).shapes[result] = (name, _named(names, args, kwargs))
    return on


def _remove_shape(args, kwargs, result):
    journal(_cid(args, kwargs, 1)).shapes.pop(_arg(args, kwargs, 0, "collisionShapeId"), None)


def _note_self_collision(j, flags, result):
    bits = int(flags or 0) & _SELF_COLLISION_BITS
    for b in result if isinstance(result, (tuple, list)) else (result,):
        if isinstance(b, int) and b >= 0:
            j.self_collision.pop(b, None)
            if bits & pybullet.URDF_USE_SELF_COLLISION:
                j.self_collision[b] = bits


_SELF_COLLISION_BITS = (pybullet.URDF_USE_SELF_COLLISION | pybullet.URDF_USE_SELF_COLLISION_INCLUDE_PARENT |
                        pybullet.URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS)


def _create_multibody(args, kwargs, result):
    j = _on_create(_cid(args, kwargs, 20), result)
    named = _named(_CREATE_BODY, args, kwargs)
    _note_maximal(j, "createMultiBody", named, result)
    _note_self_collision(j, named.get("flags"), result)


def _load_file(name, names, file_arg, i_cid, args, kwargs, result):
    """The journal's record of a body loaded from a file: (journal, named arguments with the
    file as an absolute path, that path or None if it cannot be found)."""
    j = _on_create(_cid(args, kwargs, i_cid), result)
    named = _named(names, args, kwargs)
    path = _resolve(j, named[file_arg])
    if path is not None:
        named[file_arg] = os.path.abspath(path)
    _note_maximal(j, name, named, result)
    return j, named, path


def _load_urdf(args, kwargs, result):
    j, named, path = _load_file("loadURDF", _LOAD_URDF, "fileName", 7, args, kwargs, result)
    _note_self_collision(j, named.get("flags"), result)
    _read_file_groups(j, result, path)


def _load_sdf(args, kwargs, result):
    _load_file("loadSDF", _LOAD_SDF, "sdfFileName", 3, args, kwargs, result)


def _load_mjcf(args, kwargs, result):
    j = _on_create(_cid(args, kwargs, 3), result)
    _note_self_collision(j, _arg(args, kwargs, 1, "flags", 0), result)
    path = _resolve(j, _arg(args, kwargs, 0, "mjcfFileName"))
    text = _read_text(path)
    if text is None or re.search(r"\b(contype|conaffinity)\s*=", text):
        why = "its MJCF contype/conaffinity" if text is not None else "its MJCF file could not be read"
        for b in result:
            j.filters_unknown[b] = why


def _load_bullet(args, kwargs, result):
    _on_create(_cid(args, kwargs, 1), result)


def _load_soft_body(args, kwargs, result):
    _on_create(_cid(args, kwargs, 21), result)


def _change_dynamics(args, kwargs, result):
    if len(args) > 2 or "mass" in kwargs:  # a mass change may switch a base between fixed and free
        b = int(_arg(args, kwargs, 0, "bodyUniqueId"))
        j = _structure(_cid(args, kwargs, 24), b)
        if int(_arg(args, kwargs, 1, "linkIndex")) == -1:
            # pybullet re-adds a base that switches between fixed and free with the default
            # group and mask of its new kind; the plugin re-derives them on rediscovery.
            j.group_mask.pop((b, -1), None)
            j.filters = next(_serial)


def _change_scaling(args, kwargs, result):
    _structure(_cid(args, kwargs, 2), _arg(args, kwargs, 0, "bodyUniqueId"))


def _set_filter_pair(args, kwargs, result):
    j = journal(_cid(args, kwargs, 5))
    a, b = int(_arg(args, kwargs, 0, "bodyUniqueIdA")), int(_arg(args, kwargs, 1, "bodyUniqueIdB"))
    la, lb = int(_arg(args, kwargs, 2, "linkIndexA")), int(_arg(args, kwargs, 3, "linkIndexB"))
    j.pair_rules[pair_rule_key(a, la, b, lb)] = bool(_arg(args, kwargs, 4, "enableCollision"))
    j.filters = next(_serial)


def _set_group_mask(args, kwargs, result):
    j = journal(_cid(args, kwargs, 4))
    key = int(_arg(args, kwargs, 0, "bodyUniqueId")), int(_arg(args, kwargs, 1, "linkIndexA"))
    j.group_mask[key] = (int(_arg(args, kwargs, 2, "collisionFilterGroup")),
                         int(_arg(args, kwargs, 3, "collisionFilterMask")))
    j.filters = next(_serial)


def _set_engine_parameter(args, kwargs, result):
    j = journal(_cid(args, kwargs, 27))
    mode = _arg(args, kwargs, 5, "collisionFilterMode")
    if mode is not None:
        j.filter_mode = int(mode)
        j.filters = next(_serial)
    substeps = _arg(args, kwargs, 4, "numSubSteps")
    if substeps is not None:
        j.num_substeps = int(substeps)
    if substeps is not None or _arg(args, kwargs, 0, "fixedTimeStep") is not None:
        j.params = next(_serial)


def _set_params(i):
    def on(args, kwargs, result):
        journal(_cid(args, kwargs, i)).params = next(_serial)
    return on


def _moved(i_cid, name):
    def on(args, kwargs, result):
        j = journal(_cid(args, kwargs, i_cid))
        j.moved[int(_arg(args, kwargs, 0, name))] = j.last_move = next(_serial)
    return on


def _reset_base_velocity(args, kwargs, result):
    j = journal(_cid(args, kwargs, 3))
    j.velocity_set[int(_arg(args, kwargs, 0, "objectUniqueId"))] = j.last_move = next(_serial)


def _restore_state(args, kwargs, result):
    j = journal(_cid(args, kwargs, 2))
    j.restored = j.last_move = next(_serial)


def _step(args, kwargs, result):
    j = journal(_cid(args, kwargs, 0))
    j.stepped = next(_serial)
    j.impulses.clear()


def _search_path(args, kwargs, result):
    journal(_cid(args, kwargs, 1)).search_paths.append(str(_arg(args, kwargs, 0, "path")))


# Impulses for substep replay: only recorded while the client is known to substep.
def _apply_force(args, kwargs, result):
    cid = _cid(args, kwargs, 5)
    j = journal(cid)
    if j.num_substeps <= 1:
        return
    b, link = int(_arg(args, kwargs, 0, "objectUniqueId")), int(_arg(args, kwargs, 1, "linkIndex"))
    force, pos = _arg(args, kwargs, 2, "forceObj"), _arg(args, kwargs, 3, "posObj")
    flags = int(_arg(args, kwargs, 4, "flags"))
    origin, basis = _frame(cid, b, link)
    f = _rotate(basis, force) if flags & pybullet.LINK_FRAME else tuple(float(x) for x in force)
    rel = _rotate(basis, pos) if flags & pybullet.LINK_FRAME else tuple(float(p) - o for p, o in zip(pos, origin))
    # pybullet applies the force at the frame's origin plus rel x force as a torque:
    # replayed as exactly that, whatever the frame has moved since.
    torque = (rel[1] * f[2] - rel[2] * f[1], rel[2] * f[0] - rel[0] * f[2], rel[0] * f[1] - rel[1] * f[0])
    j.impulses.append(("force", (b, link, f, torque)))


def _apply_torque(args, kwargs, result):
    cid = _cid(args, kwargs, 4)
    j = journal(cid)
    if j.num_substeps <= 1:
        return
    b, link = int(_arg(args, kwargs, 0, "objectUniqueId")), int(_arg(args, kwargs, 1, "linkIndex"))
    torque, flags = _arg(args, kwargs, 2, "torqueObj"), int(_arg(args, kwargs, 3, "flags"))
    t = _rotate(_frame(cid, b, link)[1], torque) if flags & pybullet.LINK_FRAME else tuple(float(x) for x in torque)
    j.impulses.append(("torque", (b, link, t)))


def _motor(name, i_mode, i_cid):
    def on(args, kwargs, result):
        j = journal(_cid(args, kwargs, i_cid))
        mode = int(_arg(args, kwargs, i_mode, "controlMode"))
        if mode in _PD_MODES:
            j.pd_control = True
        elif mode == pybullet.TORQUE_CONTROL and j.num_substeps > 1:
            j.impulses.append(("call", (name, args, kwargs)))  # the joint torques, cleared after each step
    return on


def _frame(cid, b, link):
    """Origin and rotation (row-major 3x3) of a body's base or link centre-of-mass frame."""
    if link == -1:
        pos, q = raw.getBasePositionAndOrientation(b, physicsClientId=cid)
    else:
        pos, q = raw.getLinkState(b, link, physicsClientId=cid)[:2]
    return pos, raw.getMatrixFromQuaternion(q)


def _rotate(m, v):
    return tuple(m[3 * i] * v[0] + m[3 * i + 1] * v[1] + m[3 * i + 2] * v[2] for i in range(3))


def replay_impulses(cid: int, impulses) -> None:
    """Apply again, through pybullet's originals, the impulses a step cleared."""
    for kind, a in impulses:
        if kind == "force":
            b, link, f, torque = a
            origin = _frame(cid, b, link)[0]
            raw.applyExternalForce(b, link, f, origin, pybullet.WORLD_FRAME, physicsClientId=cid)
            raw.applyExternalTorque(b, link, torque, pybullet.WORLD_FRAME, physicsClientId=cid)
        elif kind == "torque":
            b, link, t = a
            raw.applyExternalTorque(b, link, t, pybullet.WORLD_FRAME, physicsClientId=cid)
        else:
            name, args, kwargs = a
            getattr(raw, name)(*args, **kwargs)


# ---------------------------------------------------- URDF collision groups
def _resolve(j, name):
    """The file pybullet most likely loaded: as given, then along the search paths."""
    if name is None:
        return None
    paths = list(reversed(j.search_paths))
    try:
        import pybullet_data  # where most scripts' models come from, even unseen

        paths.append(pybullet_data.getDataPath())
    except ImportError:
        pass
    candidates = [name] + [os.path.join(d, name) for d in paths]
    return next((c for c in candidates if os.path.isfile(c)), None)


def _read_text(path):
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return f.read()
    except (OSError, TypeError):
        return None


def _read_file_groups(j, body, path):
    """The group and mask a URDF sets on its links' collisions (pybullet reads the
    ``group`` and ``mask`` attributes of a link's first collision that has them)."""
    text = _read_text(path)
    if text is None:
        if isinstance(body, int) and body >= 0:
            j.filters_unknown[body] = "its URDF file could not be read"
        return
    if not re.search(r"<collision[^>]*\b(group|mask)\s*=", text):
        return
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        j.filters_unknown[body] = "its URDF file could not be parsed"
        return
    links = {}
    for link in root.iter("link"):
        group = mask = None
        for col in link.iter("collision"):
            if group is None and "group" in col.attrib:
                group = int(col.attrib["group"])
            if mask is None and "mask" in col.attrib:
                mask = int(col.attrib["mask"])
        if group is not None or mask is not None:
            links[link.attrib.get("name", "")] = (group, mask)
    if links:
        j.file_group_mask[body] = links


# --------------------------------------------------------------- wrapping
# name -> what to note after pybullet's own function returned.
WRAPPED = {
    "resetSimulation": _reset_simulation,
    "createMultiBody": _create_multibody,
    "loadURDF": _load_urdf,
    "loadSDF": _load_sdf,
    "loadMJCF": _load_mjcf,
    "loadBullet": _load_bullet,
    "loadSoftBody": _load_soft_body,
    "removeBody": _remove_body,
    "createCollisionShape": _create_shape("createCollisionShape", _CREATE_SHAPE, 17),
    "createCollisionShapeArray": _create_shape("createCollisionShapeArray", _CREATE_SHAPES, 10),
    "removeCollisionShape": _remove_shape,
    "changeDynamics": _change_dynamics,
    "unsupportedChangeScaling": _change_scaling,
    "setCollisionFilterPair": _set_filter_pair,
    "setCollisionFilterGroupMask": _set_group_mask,
    "setPhysicsEngineParameter": _set_engine_parameter,
    "setTimeStep": _set_params(1),
    "setGravity": _set_params(3),
    "resetBasePositionAndOrientation": _moved(3, "bodyUniqueId"),
    "resetBaseVelocity": _reset_base_velocity,
    "resetJointState": _moved(4, "bodyUniqueId"),
    "resetJointStateMultiDof": _moved(4, "bodyUniqueId"),
    "resetJointStatesMultiDof": _moved(4, "bodyUniqueId"),
    "restoreState": _restore_state,
    "stepSimulation": _step,
    "setAdditionalSearchPath": _search_path,
    "applyExternalForce": _apply_force,
    "applyExternalTorque": _apply_torque,
    "setJointMotorControl2": _motor("setJointMotorControl2", 2, 9),
    "setJointMotorControlArray": _motor("setJointMotorControlArray", 2, 8),
    "setJointMotorControlMultiDof": _motor("setJointMotorControlMultiDof", 2, 10),
    "setJointMotorControlMultiDofArray": _motor("setJointMotorControlMultiDofArray", 2, 9),
}

raw = SimpleNamespace()  # pybullet's own functions, for the plugin's calls


def _wrap(name, original, note):
    def wrapper(*args, **kwargs):
        result = original(*args, **kwargs)
        note(args, kwargs, result)
        return result

    return _core.as_builtin(wrapper, name, original.__doc__ or "")


def install() -> None:
    """Wrap pybullet's world-changing functions (once per process)."""
    originals = getattr(pybullet, "_bullet_boxccd_originals", None)
    if originals is None:
        originals = {name: getattr(pybullet, name) for name in WRAPPED if hasattr(pybullet, name)}
        for name, fn in originals.items():
            setattr(pybullet, name, _wrap(name, fn, WRAPPED[name]))
        pybullet._bullet_boxccd_originals = originals
    raw.__dict__.update({k: v for k, v in vars(pybullet).items() if callable(v)})
    raw.__dict__.update(originals)


install()
