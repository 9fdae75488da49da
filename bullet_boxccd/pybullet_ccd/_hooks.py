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

A wrapper reads its call's arguments as pybullet does, from one table (``SIGNATURES``:
each function's parameter lists in the order pybullet tries them, legacy forms such as
``loadURDF(file, x, y, z)`` included), positional, keyword or mixed, with
``physicsClientId`` wherever pybullet accepts it.

Limits (BoxCCD warns where it meets them): calls made through references to
pybullet's functions taken before this package was imported (``from pybullet import
setCollisionFilterPair`` first) are not seen, nor settings made on a client before this
package was imported, nor changes made by another process connected to the same server.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from types import SimpleNamespace

import pybullet

from .. import _core

__all__ = ["Journal", "journal", "raw", "install", "new_serial", "last_serial", "replay_impulses", "position_motors",
           "joints_set_since", "WRAPPED", "SIGNATURES", "bind", "shape_type", "MjcfLoad", "OR_MODE", "DAMPING",
           "damping"]

# pybullet's default contactERP (the share of a contact's penetration its solver removes in a
# step, as a velocity of erp depth / dt): measured, setting 0.08 leaves every world bit-identical.
CONTACT_ERP = 0.08
# Bullet's default erp (joints, user constraints and joint limits: their position error is
# corrected at erp x error / dt) and frictionERP (friction anchors), which pybullet keeps.
ERP, FRICTION_ERP = 0.2, 0.2
# pybullet's default maxJointVelocity: it clamps a multibody's |v| (m/s) and |w| (rad/s) to it.
MAX_VELOCITY = 100.0
# pybullet's default linearDamping and angularDamping of a multibody, Bullet's 0.04f (a body
# made with useMaximalCoordinates=True has none by default): measured.
DAMPING = (0.03999999910593033, 0.03999999910593033)
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

    # Serial of this journal's making: tells apart clients that are given the same id in turn.
    made: int = field(default_factory=new_serial)
    reset: int = 0  # resetSimulation (everything below is cleared with it)
    closed: bool = False  # the client was disconnected (a later one under its id has a journal of its own)
    bodies: dict = field(default_factory=dict)  # body -> serial of its creation, removal, mass or scale change
    renewed: dict = field(default_factory=dict)  # body -> serial of its latest creation or removal
    last_body: int = 0  # the latest serial in ``bodies``
    created: set = field(default_factory=set)  # bodies made through the wrapped functions (provenance)
    removed: set = field(default_factory=set)  # ids removed through removeBody and not made again since
    params: int = 0  # fixedTimeStep / numSubSteps / gravity changed
    param_values: dict = field(default_factory=dict)  # those settings as last set (set again alike: no change)
    num_substeps: int = 0  # as last set through setPhysicsEngineParameter (0: never set)
    contact_erp: float = CONTACT_ERP  # as last set through setPhysicsEngineParameter (pybullet reports none)
    erp: float = ERP  # the same, of erp
    friction_erp: float = FRICTION_ERP  # the same, of frictionERP
    max_velocity: dict = field(default_factory=dict)  # body -> maxJointVelocity set through changeDynamics
    damping: dict = field(default_factory=dict)  # body -> [linear, angular] damping set through changeDynamics
    # (body, link) -> its restitution where the body is in maximal coordinates, of which
    # getDynamicsInfo reports none: the latest given through changeDynamics, else the one it was
    # made with (``shapes.Shadow``). Noted for every body: only a maximal one's is read.
    restitution: dict = field(default_factory=dict)
    # Collision filters, as pybullet's collision filter plugin keeps them.
    pair_rules: dict = field(default_factory=dict)  # (body, link, body, link) in pybullet's key order -> enable
    group_mask: dict = field(default_factory=dict)  # (body, link) -> (group, mask) set by the user
    file_group_mask: dict = field(default_factory=dict)  # body -> {link name: (group, mask)} from a URDF
    filters_unknown: dict = field(default_factory=dict)  # body -> why its file's groups could not be read
    filter_mode: int = OR_MODE
    filters: int = 0
    # Teleports: body -> serial of the user's latest pose reset (base or joints), and of
    # its latest base pose reset alone.
    moved: dict = field(default_factory=dict)
    base_moved: dict = field(default_factory=dict)
    # (body, joint) -> (its position before the first resetJointState* of it since the
    # serial given, that serial): where a joint set between steps moved a link from.
    joint_from: dict = field(default_factory=dict)
    velocity_set: dict = field(default_factory=dict)  # body -> serial of the user's latest resetBaseVelocity
    # body -> (serial, its fastest component) of the latest velocity given with a component
    # above the lowest clamp a body may have had when it was given (its maxJointVelocity then,
    # or pybullet's default): what the clamp at the next step cut is told there.
    over_clamp: dict = field(default_factory=dict)
    last_over: int = 0  # the latest serial in ``over_clamp``
    restored: int = 0  # restoreState: every body jumped
    last_move: int = 0  # the latest serial of a move: ``moved``, ``velocity_set``, ``restored``, ``stepped``
    stepped: int = 0  # serial of the user's latest direct stepSimulation (also a move of every body)
    # Settings pybullet does not report, of a client connected before this package was
    # imported, that were not set since (pybullet's defaults are assumed for them).
    unknown: set = field(default_factory=set)
    # Per-step impulses pybullet clears after every stepSimulation: replayed before each
    # substep when BoxCCD runs a world's substeps itself. (name, args) for raw calls.
    impulses: list = field(default_factory=list)
    pd_control: bool = False
    # (body, link) -> joint damping given through changeDynamics (getJointInfo keeps the file's),
    # and the serial of the latest such call.
    joint_damping: dict = field(default_factory=dict)
    last_joint_damping: int = 0
    search_paths: list = field(default_factory=list)
    # How to build again what pybullet will not describe: collision shape index ->
    # (function, kwargs) that made it, and maximal-coordinate body -> (function, kwargs,
    # index of the body in the function's result). See shapes.Shadow.
    shapes: dict = field(default_factory=dict)
    maximal: dict = field(default_factory=dict)
    # Body -> the URDF_USE_SELF_COLLISION* bits it was loaded with (loadURDF, loadMJCF,
    # createMultiBody flags): whether, and which, of its links collide with each other.
    self_collision: dict = field(default_factory=dict)
    # Body -> the loadMJCF call that made it (MjcfLoad): pybullet's getCollisionShapeData can
    # kill the process on such bodies, so their boxes are read from the file (mjcf.py).
    mjcf: dict = field(default_factory=dict)
    # Body -> {link: GEOM_* type} of the shapes createMultiBody gave it, where the journal
    # saw them made (createCollisionShape).
    link_geometry: dict = field(default_factory=dict)
    # (body, joint) -> (setJointMotorControl2's keyword arguments, serial) of the joint's
    # latest command, where it is a one-degree position motor (``position_motors``).
    motors: dict = field(default_factory=dict)

    def clear(self):
        fresh = Journal()
        fresh.search_paths = self.search_paths  # a client setting, not a world one
        self.__dict__.update(fresh.__dict__)
        self.reset = next(_serial)


_journals: dict = {}
# Clients connected when this package was imported (install): what was set on them before
# is not known. pybullet reports neither of these settings.
_connected_before: set = set()
_MAX_CLIENTS = 1024  # pybullet's MAX_PHYSICS_CLIENTS
UNREPORTED = ("contactERP", "erp", "frictionERP", "collisionFilterMode")


def journal(cid: int) -> Journal:
    """The journal of physics client ``cid`` (created empty on first use)."""
    j = _journals.get(cid)
    if j is None:
        j = _journals[cid] = Journal()
        if cid in _connected_before:
            j.unknown = set(UNREPORTED)
    return j


def pair_rule_key(body_a, link_a, body_b, link_b):
    """pybullet's key order for a pair filter (collisionFilterPlugin)."""
    if body_a > body_b or (body_a == body_b and link_a > link_b):
        return body_b, link_b, body_a, link_a
    return body_a, link_a, body_b, link_b


# --------------------------------------------------------------- arguments
class Form(tuple):
    """One parameter list pybullet's ``PyArg_ParseTupleAndKeywords`` tries for a function:
    its names in order (pybullet.c's ``kwlist``), the first ``required`` of which must be
    given, and the ``numbers`` it parses as floats (a call whose value there is no number
    does not take this form)."""

    def __new__(cls, names, required=0, numbers=()):
        self = super().__new__(cls, names)
        self.required = required
        self.numbers = frozenset(numbers)
        self.position = {n: i for i, n in enumerate(names)}
        return self


_LOAD_URDF_LEGACY4 = Form(("fileName", "startPosX", "startPosY", "startPosZ"), 4,
                          ("startPosX", "startPosY", "startPosZ"))
_LOAD_URDF_LEGACY8 = Form(("fileName", "startPosX", "startPosY", "startPosZ", "startOrnX", "startOrnY", "startOrnZ",
                           "startOrnW"), 8, ("startPosX", "startPosY", "startPosZ", "startOrnX", "startOrnY",
                                             "startOrnZ", "startOrnW"))
_MOTOR2 = ("jointIndex", "controlMode", "targetPosition", "targetVelocity", "force", "positionGain", "velocityGain",
           "maxVelocity", "physicsClientId")
_MOTOR_ARRAY = ("jointIndices", "controlMode", "targetPositions", "targetVelocities", "forces", "positionGains",
                "velocityGains", "physicsClientId")

# Every hooked function's parameter lists, in the order pybullet tries them (pybullet.c,
# 3.2.x): the one table the wrappers read their arguments from (tests/test_hooks.py checks
# it against pybullet itself). A legacy form comes first where pybullet tries it first:
# ``loadURDF(file, x, y, z)`` and ``loadURDF(file, x, y, z, qx, qy, qz, qw)`` (no client id:
# they always load into client 0); ``bodyIndex`` is the old name of ``bodyUniqueId``.
SIGNATURES = {
    "disconnect": (Form(("physicsClientId",)),),
    "resetSimulation": (Form(("flags", "physicsClientId")),),
    "createMultiBody": (Form(("baseMass", "baseCollisionShapeIndex", "baseVisualShapeIndex", "basePosition",
                              "baseOrientation", "baseInertialFramePosition", "baseInertialFrameOrientation",
                              "linkMasses", "linkCollisionShapeIndices", "linkVisualShapeIndices", "linkPositions",
                              "linkOrientations", "linkInertialFramePositions", "linkInertialFrameOrientations",
                              "linkParentIndices", "linkJointTypes", "linkJointAxis", "useMaximalCoordinates", "flags",
                              "batchPositions", "physicsClientId")),),
    "loadURDF": (_LOAD_URDF_LEGACY4, _LOAD_URDF_LEGACY8,
                 Form(("fileName", "basePosition", "baseOrientation", "useMaximalCoordinates", "useFixedBase", "flags",
                       "globalScaling", "physicsClientId"), 1)),
    "loadSDF": (Form(("sdfFileName", "useMaximalCoordinates", "globalScaling", "physicsClientId"), 1),),
    "loadMJCF": (Form(("mjcfFileName", "flags", "useMultiBody", "physicsClientId"), 1),),
    "loadBullet": (Form(("bulletFileName", "physicsClientId"), 1),),
    "loadSoftBody": (Form(("fileName", "basePosition", "baseOrientation", "scale", "mass", "collisionMargin",
                           "useMassSpring", "useBendingSprings", "useNeoHookean", "springElasticStiffness",
                           "springDampingStiffness", "springDampingAllDirections", "springBendingStiffness",
                           "NeoHookeanMu", "NeoHookeanLambda", "NeoHookeanDamping", "frictionCoeff", "useFaceContact",
                           "useSelfCollision", "repulsionStiffness", "simFileName", "physicsClientId"), 1),),
    "removeBody": (Form(("bodyUniqueId", "physicsClientId"), 1),),
    "createCollisionShape": (Form(("shapeType", "radius", "halfExtents", "height", "fileName", "meshScale",
                                   "planeNormal", "flags", "collisionFramePosition", "collisionFrameOrientation",
                                   "vertices", "indices", "heightfieldTextureScaling", "heightfieldData",
                                   "numHeightfieldRows", "numHeightfieldColumns", "replaceHeightfieldIndex",
                                   "physicsClientId"), 1),),
    "createCollisionShapeArray": (Form(("shapeTypes", "radii", "halfExtents", "lengths", "fileNames", "meshScales",
                                        "planeNormals", "flags", "collisionFramePositions",
                                        "collisionFrameOrientations", "physicsClientId"), 1),),
    "removeCollisionShape": (Form(("collisionShapeId", "physicsClientId"), 1),),
    "changeDynamics": (Form(("bodyUniqueId", "linkIndex", "mass", "lateralFriction", "spinningFriction",
                             "rollingFriction", "restitution", "linearDamping", "angularDamping", "contactStiffness",
                             "contactDamping", "frictionAnchor", "localInertiaDiagonal", "ccdSweptSphereRadius",
                             "contactProcessingThreshold", "activationState", "jointDamping", "anisotropicFriction",
                             "maxJointVelocity", "collisionMargin", "jointLowerLimit", "jointUpperLimit",
                             "jointLimitForce", "sleepThreshold", "physicsClientId"), 2),),
    "unsupportedChangeScaling": (Form(("bodyUniqueId", "scaling", "physicsClientId"), 2),),
    "setCollisionFilterPair": (Form(("bodyUniqueIdA", "bodyUniqueIdB", "linkIndexA", "linkIndexB", "enableCollision",
                                     "physicsClientId"), 5),),
    "setCollisionFilterGroupMask": (Form(("bodyUniqueId", "linkIndexA", "collisionFilterGroup", "collisionFilterMask",
                                          "physicsClientId"), 4),),
    "setPhysicsEngineParameter": (Form(("fixedTimeStep", "numSolverIterations", "useSplitImpulse",
                                        "splitImpulsePenetrationThreshold", "numSubSteps", "collisionFilterMode",
                                        "contactBreakingThreshold", "maxNumCmdPer1ms", "enableFileCaching",
                                        "restitutionVelocityThreshold", "erp", "contactERP", "frictionERP",
                                        "enableConeFriction", "deterministicOverlappingPairs", "allowedCcdPenetration",
                                        "jointFeedbackMode", "solverResidualThreshold", "contactSlop", "enableSAT",
                                        "constraintSolverType", "globalCFM", "minimumSolverIslandSize",
                                        "reportSolverAnalytics", "warmStartingFactor", "sparseSdfVoxelSize",
                                        "numNonContactInnerIterations", "physicsClientId")),),
    "setTimeStep": (Form(("timeStep", "physicsClientId"), 1),),
    "setDefaultContactERP": (Form(("defaultContactERP", "physicsClientId"), 1),),
    "setGravity": (Form(("gravX", "gravY", "gravZ", "physicsClientId"), 3),),
    "resetBasePositionAndOrientation": (Form(("bodyUniqueId", "posObj", "ornObj", "physicsClientId"), 3),),
    "resetBaseVelocity": (Form(("objectUniqueId", "linearVelocity", "angularVelocity", "physicsClientId"), 1),),
    "resetJointState": (Form(("bodyUniqueId", "jointIndex", "targetValue", "targetVelocity", "physicsClientId"), 3),),
    "resetJointStateMultiDof": (Form(("bodyUniqueId", "jointIndex", "targetValue", "targetVelocity",
                                      "physicsClientId"), 3),),
    "resetJointStatesMultiDof": (Form(("bodyUniqueId", "jointIndices", "targetValues", "targetVelocities",
                                       "physicsClientId"), 3),),
    "restoreState": (Form(("stateId", "fileName", "physicsClientId")),),
    "stepSimulation": (Form(("physicsClientId",)),),
    "setAdditionalSearchPath": (Form(("path", "physicsClientId"), 1),),
    "applyExternalForce": (Form(("objectUniqueId", "linkIndex", "forceObj", "posObj", "flags", "physicsClientId"), 5),),
    "applyExternalTorque": (Form(("objectUniqueId", "linkIndex", "torqueObj", "flags", "physicsClientId"), 4),),
    "setJointMotorControl2": (Form(("bodyUniqueId",) + _MOTOR2, 3), Form(("bodyIndex",) + _MOTOR2, 3)),
    "setJointMotorControlArray": (Form(("bodyUniqueId",) + _MOTOR_ARRAY, 3), Form(("bodyIndex",) + _MOTOR_ARRAY, 3)),
    "setJointMotorControlMultiDof": (Form(("bodyUniqueId", "jointIndex", "controlMode", "targetPosition",
                                           "targetVelocity", "force", "positionGain", "velocityGain", "maxVelocity",
                                           "damping", "physicsClientId"), 3),),
    "setJointMotorControlMultiDofArray": (Form(("bodyUniqueId", "jointIndices", "controlMode", "targetPositions",
                                                "targetVelocities", "forces", "positionGains", "velocityGains",
                                                "maxVelocities", "physicsClientId"), 3),),
}
_ALIASES = {"bodyIndex": "bodyUniqueId"}


def _is_number(x) -> bool:
    """Whether pybullet's "d" format takes x (PyFloat_AsDouble: __float__ or __index__)."""
    t = type(x)
    return hasattr(t, "__float__") or hasattr(t, "__index__")


def _fits(form, args, kwargs) -> bool:
    """Whether pybullet's parser takes a call with this form."""
    n, position = len(args), form.position
    if n > len(form):
        return False
    for k in kwargs:  # (loops, not generators: this runs on every hooked call)
        if position.get(k, -1) < n:
            return False
    for name in form[n:form.required]:
        if name not in kwargs:
            return False
    if form.numbers:
        values = dict(zip(form, args), **kwargs)
        return all(_is_number(values[k]) for k in form.numbers if k in values)
    return True


def bind(name, args, kwargs) -> dict:
    """The arguments of a call of pybullet's ``name`` by parameter name, as pybullet bound
    them (the first form of ``SIGNATURES[name]`` the call fits; the last one if none
    does), old names given their new ones; ``physicsClientId`` only where it was given."""
    forms = SIGNATURES[name]
    form = forms[-1]
    if len(forms) > 1:
        for f in forms:
            if _fits(f, args, kwargs):
                form = f
                break
    out = dict(zip(form, args))
    if kwargs:
        out.update(kwargs)
        for old, new in _ALIASES.items():
            if old in out:
                out[new] = out.pop(old)
    return out


def _cid(a) -> int:
    return int(a.get("physicsClientId", 0))


def _named(a):
    """The bound arguments without the client id (to make the same call in another client)."""
    return {k: v for k, v in a.items() if k != "physicsClientId"}


# ------------------------------------------------------------------ events
# Each takes (client, the call's arguments by name (``bind``), pybullet's result).
def _structure(cid, body):
    j = journal(cid)
    j.bodies[int(body)] = j.last_body = next(_serial)
    return j


def _forget(j, b):
    """What the journal knew of a body id that was removed or made anew."""
    j.renewed[b] = j.bodies[b]
    j.max_velocity.pop(b, None)
    j.over_clamp.pop(b, None)
    j.group_mask = {k: v for k, v in j.group_mask.items() if k[0] != b}  # they lived on its broadphase proxies
    j.file_group_mask.pop(b, None)
    j.filters_unknown.pop(b, None)
    j.maximal.pop(b, None)
    j.mjcf.pop(b, None)
    j.link_geometry.pop(b, None)
    j.damping.pop(b, None)
    j.restitution = {k: v for k, v in j.restitution.items() if k[0] != b}
    j.joint_damping = {k: v for k, v in j.joint_damping.items() if k[0] != b}
    j.joint_from = {k: v for k, v in j.joint_from.items() if k[0] != b}
    j.impulses[:] = [x for x in j.impulses if _impulse_body(x) != b]  # pybullet dropped them with the body


def _impulse_body(impulse):
    kind, a = impulse
    if kind == "call":
        named = a[1]
        return int(named.get("bodyUniqueId", named.get("bodyIndex", -1)))
    return a[0]


def damping(j, b, maximal):
    """(linear, angular) damping of body b as Bullet damps a multibody's base (``velocity_at``
    in the core); none for a maximal-coordinate body (pybullet's rigid bodies damp by
    another rule, and by none unless the user set it)."""
    return (0.0, 0.0) if maximal else tuple(j.damping.get(b, DAMPING))


def _ids(result):
    return [b for b in (result if isinstance(result, (tuple, list)) else (result,)) if isinstance(b, int) and b >= 0]


def _on_create(cid, result):
    j = journal(cid)
    s = j.last_body = next(_serial)
    for b in _ids(result):
        j.bodies[b] = s
        j.created.add(b)
        j.removed.discard(b)
        _forget(j, b)
    return j


def _remove_body(cid, a, result):
    b = int(a["bodyUniqueId"])
    j = _structure(cid, b)
    j.created.discard(b)
    j.removed.add(b)
    _forget(j, b)
    j.filters = next(_serial)  # pair rules stay: pybullet keys them by id, and a new body may reuse it


def _reset_simulation(cid, a, result):
    journal(cid).clear()


def _disconnect(cid, a, result):
    _connected_before.discard(cid)  # a client connected under its id later is seen from the start
    j = _journals.pop(cid, None)
    if j is not None:
        j.closed = True
        j.reset = next(_serial)


def _note_maximal(j, name, named, result, flag="useMaximalCoordinates"):
    if int(named.get(flag, 0) or 0) > 0:
        ids = result if isinstance(result, (tuple, list)) else (result,)
        for i, b in enumerate(ids):
            j.maximal[b] = (name, named, i)


def _create_shape(name):
    def on(cid, a, result):
        journal(cid).shapes[result] = (name, _named(a))
    return on


def _remove_shape(cid, a, result):
    journal(cid).shapes.pop(a.get("collisionShapeId"), None)


def _note_self_collision(j, flags, result):
    bits = int(flags or 0) & _SELF_COLLISION_BITS
    for b in _ids(result):
        j.self_collision.pop(b, None)
        if bits & pybullet.URDF_USE_SELF_COLLISION:
            j.self_collision[b] = bits


_SELF_COLLISION_BITS = (pybullet.URDF_USE_SELF_COLLISION | pybullet.URDF_USE_SELF_COLLISION_INCLUDE_PARENT |
                        pybullet.URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS)


def shape_type(j, index):
    """The GEOM_* type of a collision shape the journal saw being made by
    createCollisionShape, or None."""
    made = j.shapes.get(index)
    if made is None or made[0] != "createCollisionShape":
        return None
    try:
        return int(made[1].get("shapeType"))
    except (TypeError, ValueError):
        return None


def _batch_ids(cid, j, result):
    """The ids a ``createMultiBody(batchPositions=...)`` made. pybullet 3.2.x returns the last
    one and those below it, but makes the first ones under ids freed by removeBody: it then
    returns ids of bodies that were there before (whose records must stay: reading an MJCF
    body's shapes through getCollisionShapeData kills the process) and not the reused ones.
    The reused ones are read from the server's list (``syncBodyInfo``)."""
    ids = _ids(result)
    if not j.removed:
        return result
    raw.syncBodyInfo(physicsClientId=cid)
    listed = {raw.getBodyUniqueId(i, physicsClientId=cid) for i in range(raw.getNumBodies(physicsClientId=cid))}
    reused = sorted(j.removed & listed)[:len(ids)]
    return tuple(reused + sorted(ids)[len(reused):])


def _create_multibody(cid, a, result):
    named = _named(a)
    if named.get("batchPositions") is not None:
        result = _batch_ids(cid, journal(cid), result)
    j = _on_create(cid, result)
    _note_maximal(j, "createMultiBody", named, result)
    _note_self_collision(j, named.get("flags"), result)
    # The geometry type of each link's shape, where the journal made it: pybullet prints an
    # error for a heightfield's getCollisionShapeData, which BoxCCD then does not call.
    shapes = {-1: named.get("baseCollisionShapeIndex", -1)}
    try:
        shapes.update(enumerate(named.get("linkCollisionShapeIndices") or ()))
    except TypeError:
        pass
    kinds = {}
    for link, index in shapes.items():
        try:
            kind = shape_type(j, int(index))
        except (TypeError, ValueError):
            kind = None
        if kind is not None:
            kinds[link] = kind
    for b in _ids(result):
        j.link_geometry[b] = kinds


def _load_file(name, file_arg, cid, a, result):
    """The journal's record of a body loaded from a file: (journal, named arguments with the
    file as an absolute path, that path or None if it cannot be found)."""
    j = _on_create(cid, result)
    named = _named(a)
    path = _resolve(j, named.get(file_arg))
    if path is not None:
        named[file_arg] = os.path.abspath(path)
    _note_maximal(j, name, named, result)
    return j, named, path


def _load_urdf(cid, a, result):
    if "startPosX" in a:  # loadURDF(file, x, y, z[, qx, qy, qz, qw]): pybullet's legacy forms
        a = {"fileName": a["fileName"], "basePosition": [float(a[k]) for k in ("startPosX", "startPosY", "startPosZ")],
             "baseOrientation": [float(a.get(k, 0.0)) for k in ("startOrnX", "startOrnY", "startOrnZ")] +
                                [float(a.get("startOrnW", 1.0))]}
    j, named, path = _load_file("loadURDF", "fileName", cid, a, result)
    _note_self_collision(j, named.get("flags"), result)
    _read_file_groups(j, result, path)


def _load_sdf(cid, a, result):
    _load_file("loadSDF", "sdfFileName", cid, a, result)


@dataclass
class MjcfLoad:
    """One loadMJCF call: the file (None: not found), the bodies it made in order, and how
    (``flags``, ``multibody``: useMultiBody). ``mapping`` caches which of the file's models
    each body is (``mjcf.match``)."""

    path: object
    bodies: tuple
    flags: int
    multibody: bool
    mapping: object = None


def _load_mjcf(cid, a, result):
    j = _on_create(cid, result)
    _note_self_collision(j, a.get("flags", 0), result)
    path = _resolve(j, a.get("mjcfFileName"))
    load = MjcfLoad(None if path is None else os.path.abspath(path), tuple(_ids(result)), int(a.get("flags", 0) or 0),
                    int(a.get("useMultiBody", 1)) != 0)
    for b in load.bodies:
        j.mjcf[b] = load


def _load_bullet(cid, a, result):
    _on_create(cid, result)


def _load_soft_body(cid, a, result):
    _on_create(cid, result)


def _change_dynamics(cid, a, result):
    if a.get("jointDamping") is not None and float(a["jointDamping"]) >= 0.0:  # (pybullet ignores one below 0)
        j = journal(cid)
        j.joint_damping[(int(a["bodyUniqueId"]), int(a["linkIndex"]))] = float(a["jointDamping"])
        j.last_joint_damping = next(_serial)
    if a.get("restitution") is not None and float(a["restitution"]) >= 0.0:  # (pybullet ignores one below 0)
        journal(cid).restitution[int(a["bodyUniqueId"]), int(a["linkIndex"])] = float(a["restitution"])
    if a.get("maxJointVelocity") is not None:
        journal(cid).max_velocity[int(a["bodyUniqueId"])] = float(a["maxJointVelocity"])
    given = {k: float(a[name]) for k, name in enumerate(("linearDamping", "angularDamping"))
             if a.get(name) is not None and float(a[name]) >= 0.0}  # pybullet ignores a negative one
    if given:
        b = int(a["bodyUniqueId"])
        damping = _structure(cid, b).damping.setdefault(b, list(DAMPING))  # (read again: it is in the tables)
        for k, x in given.items():
            damping[k] = x
    if "mass" in a:  # a mass change may switch a base between fixed and free
        b = int(a["bodyUniqueId"])
        j = _structure(cid, b)
        if int(a["linkIndex"]) == -1:
            # pybullet re-adds a base that switches between fixed and free with the default
            # group and mask of its new kind; the plugin re-derives them on rediscovery.
            j.group_mask.pop((b, -1), None)
            j.filters = next(_serial)


def _change_scaling(cid, a, result):
    _structure(cid, a["bodyUniqueId"])


def _set_filter_pair(cid, a, result):
    j = journal(cid)
    key = pair_rule_key(int(a["bodyUniqueIdA"]), int(a["linkIndexA"]), int(a["bodyUniqueIdB"]), int(a["linkIndexB"]))
    j.pair_rules[key] = bool(a["enableCollision"])
    j.filters = next(_serial)


def _set_group_mask(cid, a, result):
    j = journal(cid)
    j.group_mask[(int(a["bodyUniqueId"]), int(a["linkIndexA"]))] = (int(a["collisionFilterGroup"]),
                                                                     int(a["collisionFilterMask"]))
    j.filters = next(_serial)


def _set_engine_parameter(cid, a, result):
    j = journal(cid)
    mode = a.get("collisionFilterMode")
    if mode is not None:
        j.filter_mode = int(mode)
        j.filters = next(_serial)
        j.unknown.discard("collisionFilterMode")
    substeps = a.get("numSubSteps")
    if substeps is not None:
        j.num_substeps = int(substeps)
    for key, name in (("contactERP", "contact_erp"), ("erp", "erp"), ("frictionERP", "friction_erp")):
        if a.get(key) is not None:
            setattr(j, name, float(a[key]))
            j.unknown.discard(key)
    _params_set(j, {k: a[k] for k in ("fixedTimeStep", "numSubSteps") if a.get(k) is not None})


def _set_contact_erp(cid, a, result):
    j = journal(cid)
    j.contact_erp = float(a["defaultContactERP"])  # the same setting as contactERP (measured)
    j.unknown.discard("contactERP")


def _set_params(cid, a, result):
    named = _named(a)
    if "timeStep" in named:  # setTimeStep sets what setPhysicsEngineParameter calls fixedTimeStep
        named["fixedTimeStep"] = named.pop("timeStep")
    _params_set(journal(cid), named)


def _params_set(j, values):
    """Note settings of the time step, substeps or gravity; those set to what they were
    last set to change nothing (a script that sets its time step every step)."""
    changed = False
    for k, v in values.items():
        try:
            v = tuple(float(x) for x in v) if isinstance(v, (list, tuple)) else float(v)
        except (TypeError, ValueError):
            v = None  # pybullet took it; what it means is read back at the next step
        changed |= v is None or j.param_values.get(k) != v
        j.param_values[k] = v
    if changed:
        j.params = next(_serial)


def _moved(cid, a, result):
    j = journal(cid)
    j.moved[int(a["bodyUniqueId"])] = j.last_move = next(_serial)


def joints_set_since(cid: int, serial: int) -> dict:
    """{body: {joint: its position (a list) before it was first set by resetJointState*
    after ``serial``}}; forgets every earlier such position."""
    j = journal(cid)
    out = {}
    for (b, joint), (q, when) in j.joint_from.items():
        if when > serial:
            out.setdefault(b, {})[joint] = q
    j.joint_from.clear()
    return out


def _joints_before(cid, a):
    """Before a resetJointState*: keep each joint's position, where not kept already."""
    j = journal(cid)
    b = int(a["bodyUniqueId"])
    joints = a["jointIndices"] if "jointIndices" in a else [a["jointIndex"]]
    for joint in map(int, joints):
        if (b, joint) not in j.joint_from:
            j.joint_from[b, joint] = (list(raw.getJointStateMultiDof(b, joint, physicsClientId=cid)[0]),
                                      next(_serial))


def _base_moved(cid, a, result):
    _moved(cid, a, result)
    j = journal(cid)
    j.base_moved[int(a["bodyUniqueId"])] = j.last_move


def _reset_base_velocity(cid, a, result):
    j = journal(cid)
    b = int(a["objectUniqueId"])
    j.velocity_set[b] = j.last_move = next(_serial)
    fastest = max(_fastest(a.get("linearVelocity")), _fastest(a.get("angularVelocity")))
    if fastest > min(MAX_VELOCITY, j.max_velocity.get(b, MAX_VELOCITY)):
        j.over_clamp[b] = (j.last_move, fastest)
        j.last_over = j.last_move


def _fastest(vector):
    """The largest magnitude of a component of a vector pybullet took (any sequence of
    numbers, a numpy array); 0 if none."""
    try:
        return max((abs(float(x)) for x in vector), default=0.0) if vector is not None else 0.0
    except (TypeError, ValueError):
        return 0.0


def _restore_state(cid, a, result):
    j = journal(cid)
    j.restored = j.last_move = next(_serial)


def _step(cid, a, result):
    j = journal(cid)
    j.stepped = j.last_move = next(_serial)
    j.impulses.clear()


def _search_path(cid, a, result):
    journal(cid).search_paths.append(str(a["path"]))


# Impulses pybullet clears after every stepSimulation, recorded for BoxCCD to apply again
# before each substep it takes and each partial step from a contact.
def _apply_force(cid, a, result):
    j = journal(cid)
    b, link = int(a["objectUniqueId"]), int(a["linkIndex"])
    force, pos, flags = a["forceObj"], a["posObj"], int(a["flags"])
    frame = _frame(cid, b, link)
    if frame is None:  # pybullet ignored the call
        return
    origin, basis = frame
    f = _rotate(basis, force) if flags & pybullet.LINK_FRAME else tuple(float(x) for x in force)
    rel = _rotate(basis, pos) if flags & pybullet.LINK_FRAME else tuple(float(p) - o for p, o in zip(pos, origin))
    # pybullet applies the force at the frame's origin plus rel x force as a torque:
    # replayed as exactly that, whatever the frame has moved since.
    torque = (rel[1] * f[2] - rel[2] * f[1], rel[2] * f[0] - rel[0] * f[2], rel[0] * f[1] - rel[1] * f[0])
    j.impulses.append(("force", (b, link, f, torque)))


def _apply_torque(cid, a, result):
    j = journal(cid)
    b, link = int(a["objectUniqueId"]), int(a["linkIndex"])
    torque, flags = a["torqueObj"], int(a["flags"])
    frame = _frame(cid, b, link)
    if frame is None:  # pybullet ignored the call
        return
    t = _rotate(frame[1], torque) if flags & pybullet.LINK_FRAME else tuple(float(x) for x in torque)
    j.impulses.append(("torque", (b, link, t)))


def _motor(name):
    def on(cid, a, result):
        j = journal(cid)
        mode = int(a["controlMode"])
        if mode in _PD_MODES:
            j.pd_control = True
        elif mode == pybullet.TORQUE_CONTROL:
            j.impulses.append(("call", (name, a)))  # the joint torques, cleared after each step
        joints = a.get("jointIndices", a.get("jointIndex"))
        _note_motor_call((name, a.get("bodyUniqueId"), tuple(joints) if name.endswith("Array") else joints, cid),
                         (name, None, a, _serial.last))
    return on


# Motor calls, with the serial current when made, each the latest of its function, body,
# joints and client, in the order of those latest calls: the position and velocity motors
# of robot code, given at every step, unbound (``_wrap``), the others bound. They are read
# into each client's ``Journal.motors`` when asked for, or when many different ones pile up.
_motor_calls: dict = {}
_MOTOR_CALLS_HELD = 4096
_CID_AT = {"setJointMotorControl2": 9, "setJointMotorControlArray": 8, "setJointMotorControlMultiDof": 10,
           "setJointMotorControlMultiDofArray": 9}  # where a positional physicsClientId stands


def _note_motor_call(key, call):
    _motor_calls.pop(key, None)
    _motor_calls[key] = call
    if len(_motor_calls) > _MOTOR_CALLS_HELD:
        _read_motor_calls()


def _unbound_motor_call(name, args, kwargs):
    """Keep a motor call of a silent mode as given: keyed by its function, body, joints and
    client where they stand where robot code puts them (else by the call alone)."""
    try:
        if len(args) < 2 or len(args) > _CID_AT[name] + 1:
            raise TypeError
        joints = tuple(args[1]) if name.endswith("Array") else args[1]
        cid = args[-1] if len(args) == _CID_AT[name] + 1 else kwargs.get("physicsClientId", 0)
        key = (name, args[0], joints, cid)
        hash(key)
    except (TypeError, KeyError):
        key = object()
    _note_motor_call(key, (name, args, kwargs, _serial.last))


# setJointMotorControl2's keyword arguments and setJointMotorControlArray's for the same.
_MOTOR_KEYS = (("targetPosition", "targetPositions"), ("targetVelocity", "targetVelocities"),
               ("force", "forces"), ("positionGain", "positionGains"), ("velocityGain", "velocityGains"),
               ("maxVelocity", None))


def _read_motor_calls():
    """Fold the motor calls made since the last fold into their clients' ``motors``: a
    joint's one-degree POSITION_CONTROL command (setJointMotorControl2 or Array) is kept
    with the serial current when it was given; any other command to the joint drops it.
    A call made before its body was removed or its world reset is dropped."""
    calls = list(_motor_calls.values())
    _motor_calls.clear()
    for name, args, kwargs, serial in calls:
        a = kwargs if args is None else bind(name, args, kwargs)
        j = _journals.get(_cid(a))
        if j is None:
            continue
        try:
            body, mode = int(a["bodyUniqueId"]), int(a["controlMode"])
            if j.reset > serial or j.renewed.get(body, 0) > serial:
                continue
            if name.endswith("Array"):
                joints = [int(k) for k in a["jointIndices"]]
                given = [[(one, a[many][i]) for one, many in _MOTOR_KEYS if many and a.get(many) is not None]
                         for i in range(len(joints))]
            else:
                joints = [int(a["jointIndex"])]
                given = [[(one, a[one]) for one, _ in _MOTOR_KEYS if a.get(one) is not None]]
        except (KeyError, TypeError, ValueError, IndexError):  # pybullet refused it too
            continue
        keep = mode == pybullet.POSITION_CONTROL and "MultiDof" not in name
        for joint, kw in zip(joints, given):
            if keep:
                j.motors[body, joint] = ({k: float(v) for k, v in kw}, serial)
            else:
                j.motors.pop((body, joint), None)


def position_motors(cid: int) -> dict:
    """{(body, joint): setJointMotorControl2's keyword arguments} of the one-degree position
    motors the user gave client ``cid``'s bodies that are still in its world."""
    _read_motor_calls()
    j = journal(cid)
    gone = [k for k, (_, serial) in j.motors.items() if j.reset > serial or j.renewed.get(k[0], 0) > serial]
    for k in gone:
        del j.motors[k]
    return {k: kw for k, (kw, _) in j.motors.items()}


def _frame(cid, b, link):
    """Origin and rotation (row-major 3x3) of a body's base or link centre-of-mass frame;
    None if pybullet has no such body or link (it ignores a force or torque given there)."""
    try:
        if link == -1:
            pos, q = raw.getBasePositionAndOrientation(b, physicsClientId=cid)
        elif 0 <= link < raw.getNumJoints(b, physicsClientId=cid):
            pos, q = raw.getLinkState(b, link, physicsClientId=cid)[:2]
        else:
            return None
    except pybullet.error:
        return None
    return pos, raw.getMatrixFromQuaternion(q)


def _rotate(m, v):
    return tuple(m[3 * i] * v[0] + m[3 * i + 1] * v[1] + m[3 * i + 2] * v[2] for i in range(3))


def replay_impulses(cid: int, impulses) -> None:
    """Apply again, through pybullet's originals, the impulses a step cleared."""
    for kind, a in impulses:
        if kind == "force":
            b, link, f, torque = a
            frame = _frame(cid, b, link)
            if frame is None:  # removed since
                continue
            raw.applyExternalForce(b, link, f, frame[0], pybullet.WORLD_FRAME, physicsClientId=cid)
            raw.applyExternalTorque(b, link, torque, pybullet.WORLD_FRAME, physicsClientId=cid)
        elif kind == "torque":
            b, link, t = a
            raw.applyExternalTorque(b, link, t, pybullet.WORLD_FRAME, physicsClientId=cid)
        else:
            name, named = a
            getattr(raw, name)(**named)


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
# name -> what to note after pybullet's own function returned (its arguments read by
# ``SIGNATURES``, which names every function here).
WRAPPED = {
    "disconnect": _disconnect,
    "resetSimulation": _reset_simulation,
    "createMultiBody": _create_multibody,
    "loadURDF": _load_urdf,
    "loadSDF": _load_sdf,
    "loadMJCF": _load_mjcf,
    "loadBullet": _load_bullet,
    "loadSoftBody": _load_soft_body,
    "removeBody": _remove_body,
    "createCollisionShape": _create_shape("createCollisionShape"),
    "createCollisionShapeArray": _create_shape("createCollisionShapeArray"),
    "removeCollisionShape": _remove_shape,
    "changeDynamics": _change_dynamics,
    "unsupportedChangeScaling": _change_scaling,
    "setCollisionFilterPair": _set_filter_pair,
    "setCollisionFilterGroupMask": _set_group_mask,
    "setPhysicsEngineParameter": _set_engine_parameter,
    "setDefaultContactERP": _set_contact_erp,
    "setTimeStep": _set_params,
    "setGravity": _set_params,
    "resetBasePositionAndOrientation": _base_moved,
    "resetBaseVelocity": _reset_base_velocity,
    "resetJointState": _moved,
    "resetJointStateMultiDof": _moved,
    "resetJointStatesMultiDof": _moved,
    "restoreState": _restore_state,
    "stepSimulation": _step,
    "setAdditionalSearchPath": _search_path,
    "applyExternalForce": _apply_force,
    "applyExternalTorque": _apply_torque,
    "setJointMotorControl2": _motor("setJointMotorControl2"),
    "setJointMotorControlArray": _motor("setJointMotorControlArray"),
    "setJointMotorControlMultiDof": _motor("setJointMotorControlMultiDof"),
    "setJointMotorControlMultiDofArray": _motor("setJointMotorControlMultiDofArray"),
}

raw = SimpleNamespace()  # pybullet's own functions, for the plugin's calls


# Motor modes a motor call notes nothing for (position and velocity motors are
# constraints pybullet keeps across steps). Every motor function takes its mode third
# (``_MOTOR2``, ``_MOTOR_ARRAY``, ``SIGNATURES``): a call in one of these modes is
# passed on without binding its arguments, the per-step call of most robot code.
_SILENT_MODES = frozenset((pybullet.POSITION_CONTROL, pybullet.VELOCITY_CONTROL))


def _silent_motor(args, kwargs) -> bool:
    mode = args[2] if len(args) > 2 else kwargs.get("controlMode")
    try:
        return mode in _SILENT_MODES
    except TypeError:  # unhashable: pybullet's parser refused it already, or bind will say
        return False


# Notes taken before the call (what it changes is read first).
_BEFORE = {"resetJointState": _joints_before, "resetJointStateMultiDof": _joints_before,
           "resetJointStatesMultiDof": _joints_before}


def _wrap(name, original, note):
    silent = _silent_motor if name.startswith("setJointMotorControl") else None
    before = _BEFORE.get(name)

    def wrapper(*args, **kwargs):
        if before is not None:
            try:
                a = bind(name, args, kwargs)
                before(_cid(a), a)
            except (pybullet.error, KeyError, TypeError, ValueError):
                pass  # a call pybullet refuses (it says why)
        result = original(*args, **kwargs)
        if silent is None or not silent(args, kwargs):
            a = bind(name, args, kwargs)
            note(_cid(a), a, result)
        else:
            _unbound_motor_call(name, args, kwargs)
        return result

    return _core.as_builtin(wrapper, name, original.__doc__ or "")


def install() -> None:
    """Wrap pybullet's world-changing functions (once per process)."""
    originals = getattr(pybullet, "_bullet_boxccd_originals", None)
    if originals is None:
        _connected_before.update(i for i in range(_MAX_CLIENTS)
                                 if pybullet.getConnectionInfo(physicsClientId=i)["isConnected"])
        originals = {name: getattr(pybullet, name) for name in WRAPPED if hasattr(pybullet, name)}
        for name, fn in originals.items():
            setattr(pybullet, name, _wrap(name, fn, WRAPPED[name]))
        pybullet._bullet_boxccd_originals = originals
    raw.__dict__.update({k: v for k, v in vars(pybullet).items() if callable(v)})
    raw.__dict__.update(originals)


install()
