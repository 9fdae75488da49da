"""The boxes of bodies loaded by ``loadMJCF``, read from their file as pybullet builds them.

pybullet 3.2.x's ``getCollisionShapeData`` kills the process (SIGSEGV) on links of MJCF
bodies: its MJCF importer keeps a capsule given by ``fromto`` as a ``btMultiSphereShape``,
which ``extractCollisionShapes`` reads as a ``btCapsuleShapeZ``. So BoxCCD never calls it
on a body the journal saw ``loadMJCF`` make: it parses the file the way pybullet's importer
(examples/Importers/ImportMJCFDemo/BulletMJCFImporter.cpp) does, and maps the result onto
the body's links. Replicated, not MuJoCo's semantics:

* models: each ``<body>`` and ``<geom>`` directly in ``<worldbody>`` (and in a ``<body>``
  directly under ``<mujoco>``, read first) is a model, i.e. a pybullet body, in file order;
* links: a ``<body>`` is a link named after it (``link{model}_{n}`` if unnamed); each of
  its joints adds a further (geometry-less) link, and a root body with a joint other than
  ``free`` a geometry-less root; a joint of a type other than fixed, slide and hinge makes
  no joint, so its link and what hangs from it are left out of the body (they are not
  simulated). The body's links are the first root's subtree, numbered depth first;
* geoms: ``type`` box, sphere, capsule, cylinder, plane, mesh; a geom's frame in its link
  is ``pos`` and ``quat`` (w x y z) or ``axisangle`` (radians, whatever ``<compiler
  angle>`` says); ``euler``, ``xyaxes``, ``zaxis`` and a box's ``fromto`` are ignored, as
  pybullet ignores them; numbers go through float32 as in the importer; a box's ``size``
  is its half extents;
* the link's centre-of-mass frame is its ``<inertial>`` pos/quat, or else has the origin
  of the mid-point of the last geom's ``fromto`` (capsule or cylinder) and no rotation; a
  box's frame in it is (inertial)^-1 (geom);
* collision filters: a link's group and mask are the ``contype`` and ``conaffinity`` of
  its last geom, else of ``<default>`` (``<default class>`` through a body's
  ``childclass``; a geom's ``class`` is ignored), else 1 and 1.

``tests/test_hooks.py`` compares the result with pybullet's own getCollisionShapeData, in
a subprocess, on links where that call is safe.
"""

from __future__ import annotations

import itertools
import math
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

__all__ = ["MjcfLink", "MjcfModel", "read_models", "match", "NotMappable"]

_INVALID = -2
_IMPLICIT_CYLINDER = 128  # URDF_USE_IMPLICIT_CYLINDER (CUF_USE_IMPLICIT_CYLINDER)
_MAINTAIN_LINK_ORDER = 131072  # URDF_MAINTAIN_LINK_ORDER
_NUMBER = re.compile(r"\s*[+-]?(inf(inity)?|nan|(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?)", re.IGNORECASE)


class NotMappable(Exception):
    """A file, or a body, whose boxes cannot be placed on pybullet's links."""


@dataclass
class MjcfLink:
    """One pybullet link (or base) of an MJCF body."""

    name: str
    boxes: list = field(default_factory=list)  # [(half (3,), X_CS (4, 4))] in the link's centre-of-mass frame
    planes: list = field(default_factory=list)  # [X_CS (4, 4)]: a plane's frame (normal +z) in that frame
    others: list = field(default_factory=list)  # geometry names of its other shapes
    multisphere: bool = False  # it has a shape getCollisionShapeData crashes on
    group_mask: tuple | None = None  # (contype, conaffinity) of its last geom; None: no geom


@dataclass
class MjcfModel:
    """One pybullet body of an MJCF file: ``links[0]`` is the base (link -1), ``links[i + 1]``
    link i."""

    links: list

    @property
    def root_name(self) -> str:
        return self.links[0].name


# ----------------------------------------------------------- number parsing
def _atof(text) -> float:
    """C's atof: the longest leading number, 0 if none."""
    m = _NUMBER.match(text or "")
    return float(m.group(0)) if m else 0.0


def _floats(text):
    """The importer's numbers: split at single spaces, each through atof and float32."""
    return [float(np.float32(_atof(s))) for s in (text or "").split(" ") if s]


def _vec3(text):
    v = _floats(text)
    return np.array(v[:3]) if len(v) >= 3 else None


def _vec4(text):
    v = _floats(text)
    return v if len(v) == 4 else None


def _int(text) -> int:
    x = _atof(text)
    return int(x) if math.isfinite(x) else 0


def _rotation(x, y, z, w) -> np.ndarray:
    """btMatrix3x3::setRotation: the rotation of a quaternion, of any length. Bullet's own
    arithmetic, as the importer computes the frames (motion.quat_to_matrix rounds otherwise),
    so it stays apart from that helper."""
    d = x * x + y * y + z * z + w * w
    s = 2.0 / d
    xs, ys, zs = x * s, y * s, z * s
    wx, wy, wz = w * xs, w * ys, w * zs
    xx, xy, xz = x * xs, x * ys, x * zs
    yy, yz, zz = y * ys, y * zs, z * zs
    return np.array([[1.0 - (yy + zz), xy - wz, xz + wy],
                     [xy + wz, 1.0 - (xx + zz), yz - wx],
                     [xz - wy, yz + wx, 1.0 - (xx + yy)]])


def _axis_angle(ax, ay, az, angle) -> np.ndarray:
    d = math.sqrt(ax * ax + ay * ay + az * az)
    s = math.sin(0.5 * angle) / d
    return _rotation(ax * s, ay * s, az * s, math.cos(0.5 * angle))


# ------------------------------------------------------------------ parsing
@dataclass
class _Defaults:
    group: int = 1
    mask: int = 1


@dataclass
class _Link:
    name: str
    collisions: list = field(default_factory=list)  # (kind, half or None, X_LG, group, mask, multisphere)
    inertial: np.ndarray = field(default_factory=lambda: np.eye(4))
    parent: object = None
    children: list = field(default_factory=list)


class _Model:
    def __init__(self):
        self.links = {}  # name -> _Link, in creation order (pybullet's btHashMap)
        self.joints = {}  # key -> (parent name, child name), in creation order


class _Parser:
    def __init__(self, path, flags):
        self.path, self.flags = path, flags
        self.defaults = _Defaults()
        self.classes = {}
        self.assets = {}
        self.models = []
        self.uid = itertools.count()

    def parse(self, root):
        if root.tag != "mujoco":
            raise NotMappable("no <mujoco> root element")
        for d in root.findall("default"):
            self.parse_defaults(self.defaults, d)
        mesh_dir = ""
        for c in root.findall("compiler"):
            mesh_dir = c.get("meshdir", mesh_dir)
        for a in root.findall("asset"):
            for m in a.findall("mesh"):
                if m.get("name") is not None and m.get("file") is not None:
                    self.assets[m.get("name")] = mesh_dir + m.get("file")
        for elem in root.findall("body") + root.findall("worldbody"):
            self.parse_root_level(elem)
        return self.models

    def parse_defaults(self, defaults, elem):
        for child in elem:
            if "default" in child.tag and child.get("class") is not None:
                self.parse_defaults(self.classes.setdefault(child.get("class"), _Defaults()), child)
            if child.tag == "geom":
                if child.get("contype") is not None:
                    defaults.group = _int(child.get("contype"))
                if child.get("conaffinity") is not None:
                    defaults.mask = _int(child.get("conaffinity"))

    def parse_root_level(self, elem):
        for child in elem:
            if child.tag == "body":
                model = _Model()
                self.models.append(model)
                self.parse_body(self.defaults, child, model, _INVALID)
            elif child.tag == "geom":
                model = _Model()
                self.models.append(model)
                link = _Link(child.get("name", "anonymous"))
                model.links[link.name] = link
                self.parse_geom(self.defaults, child, link)

    def create(self, model, name=None) -> int:
        index = len(model.links)
        name = f"link{self.models.index(model)}_{index}" if name is None else name
        if name in model.links:
            raise NotMappable(f"two links named {name!r}")
        model.links[name] = _Link(name)
        return index

    @staticmethod
    def link(model, index) -> _Link:
        return list(model.links.values())[index]

    def parse_body(self, defaults, elem, model, org_parent):
        cur = self.classes.get(elem.get("childclass"), defaults) if elem.get("childclass") is not None else defaults
        org_child = self.create(model, elem.get("name"))
        link = self.link(model, org_child)
        inertial, mass_defined = np.eye(4), False
        new_parent, has_joint = org_parent, False
        for x in elem:
            if x.tag == "inertial":
                pos, quat = _vec3(x.get("pos")), _vec4(x.get("quat"))
                if pos is not None:
                    inertial[:3, 3] = pos
                if quat is not None:
                    inertial[:3, :3] = _rotation(quat[1], quat[2], quat[3], quat[0])
                mass_defined = True
            elif x.tag == "joint":
                if not has_joint:
                    if new_parent != _INVALID or (x.get("type") or "") != "free":
                        if new_parent == _INVALID:
                            new_parent = self.create(model)
                        new_link = self.create(model)
                        self.joint(model, x, new_parent, new_link)
                        new_parent, has_joint = new_link, True
                else:
                    new_link = self.create(model)
                    self.joint(model, x, new_parent, new_link)
                    new_parent = new_link
            elif x.tag == "geom":
                shift = self.parse_geom(cur, x, link)
                if not mass_defined:
                    inertial[:3, 3] = shift
            elif x.tag == "body":
                self.parse_body(cur, x, model, org_child)
        link.inertial = inertial
        if new_parent != _INVALID:  # the body's link hangs from its last joint (or its parent) by a fixed joint
            model.joints[("fixed", next(self.uid))] = (self.link(model, new_parent).name, link.name)

    def joint(self, model, x, parent, child):
        if x.get("type") in ("fixed", "slide", "hinge"):
            key = x.get("name") if x.get("name") is not None else ("joint", next(self.uid))
            model.joints[key] = (self.link(model, parent).name, self.link(model, child).name)

    def parse_geom(self, defaults, x, link) -> np.ndarray:
        """Adds the geom's collision to the link; returns its inertial shift."""
        X = np.eye(4)
        pos, quat, axis_angle = _vec3(x.get("pos")), _vec4(x.get("quat")), _vec4(x.get("axisangle"))
        if pos is not None:
            X[:3, 3] = pos
        if quat is not None:
            X[:3, :3] = _rotation(quat[1], quat[2], quat[3], quat[0])
        if axis_angle is not None:
            X[:3, :3] = _axis_angle(*axis_angle)
        kind, size, shift, half, multisphere = x.get("type"), x.get("size"), np.zeros(3), None, False
        handled = False
        if kind == "plane" or kind == "sphere":
            handled = True
        elif kind == "box":
            half = np.ones(3) if size is None else _vec3(size)
            half = np.zeros(3) if half is None else half
            handled = True
        elif kind in ("capsule", "cylinder"):
            sizes = _floats(size)
            ends = _floats(x.get("fromto")) if x.get("fromto") is not None else None
            if ends is not None:
                ends = (ends + [0.0] * 6)[:6] if len(ends) >= 6 else [0.0] * 6
                shift = 0.5 * (np.array(ends[:3]) + np.array(ends[3:]))
                multisphere = kind == "capsule" and not (self.flags & _IMPLICIT_CYLINDER)
                handled = True
            else:
                handled = len(sizes) >= 2
        elif kind == "mesh":
            asset = self.assets.get(x.get("mesh"))
            if asset is not None:
                base = os.path.dirname(self.path)
                handled = any(os.path.isfile(c) for c in (asset, os.path.join(base, asset)))
        if handled:
            group = _int(x.get("contype")) if x.get("contype") is not None else defaults.group
            mask = _int(x.get("conaffinity")) if x.get("conaffinity") is not None else defaults.mask
            link.collisions.append((kind, half, X, group, mask, multisphere))
        return shift


def _finish(model: _Model, flags) -> MjcfModel | None:
    """pybullet's body of a parsed model (initTreeAndRoot, then its multibody's link order:
    depth first, or with URDF_MAINTAIN_LINK_ORDER initTreeAndRoot's), or None if it has no
    root (pybullet makes no body of it)."""
    for parent, child in model.joints.values():
        c, p = model.links.get(child), model.links.get(parent)
        if c is None or p is None:
            raise NotMappable(f"a joint between links {parent!r} and {child!r} that do not exist")
        c.parent = p
        p.children.append(c)
    roots = [lk for lk in model.links.values() if lk.parent is None]
    if not roots:
        return None
    if flags & _MAINTAIN_LINK_ORDER:
        order = [roots[0]]

        def add(lk):
            order.extend(lk.children)
            for c in lk.children:
                add(c)

        add(roots[0])
    else:
        order, stack = [], [roots[0]]
        while stack:
            lk = stack.pop()
            order.append(lk)
            stack.extend(reversed(lk.children))
    links = []
    for lk in order:
        out = MjcfLink(lk.name)
        inverse = np.linalg.inv(lk.inertial)
        for kind, half, X_LG, group, mask, multisphere in lk.collisions:
            if kind == "box":
                out.boxes.append((half, inverse @ X_LG))
            elif kind == "plane":
                out.planes.append(inverse @ X_LG)
            else:
                out.others.append(kind)
            out.multisphere |= multisphere
            out.group_mask = (group, mask)
        links.append(out)
    return MjcfModel(links)


_cache: dict = {}


def read_models(path, flags=0) -> list:
    """The bodies pybullet makes of an MJCF file, in order (a model without a root makes
    no body: None). Raises NotMappable, OSError or ET.ParseError."""
    st = os.stat(path)
    flags &= _IMPLICIT_CYLINDER | _MAINTAIN_LINK_ORDER
    key = (path, st.st_mtime_ns, st.st_size, flags)
    if key not in _cache:
        parser = _Parser(path, flags)
        models = parser.parse(ET.parse(path).getroot())
        _cache[key] = [_finish(m, flags) for m in models]
    return _cache[key]


def _signature(raw, cid, body, multibody):
    """(root link name, link names or None) of a body as pybullet reports them."""
    info = raw.getBodyInfo(body, physicsClientId=cid)
    if not multibody:  # a maximal-coordinate body keeps only its root: its name is the body's
        return info[1].decode("utf-8", "replace"), None
    n = raw.getNumJoints(body, physicsClientId=cid)
    names = [raw.getJointInfo(body, j, physicsClientId=cid)[12].decode("utf-8", "replace") for j in range(n)]
    return info[0].decode("utf-8", "replace"), names


def match(raw, cid, load) -> dict:
    """{body: MjcfModel or the reason it has none} for the bodies of one loadMJCF call
    (``_hooks.MjcfLoad``): the file's models in order, each body the next model whose link
    names are the body's (pybullet skips a model it makes no body of)."""
    if load.path is None:
        return dict.fromkeys(load.bodies, "its MJCF file was not found")
    try:
        models = [m for m in read_models(load.path, load.flags) if m is not None]
    except (OSError, ET.ParseError, NotMappable, ValueError, ZeroDivisionError) as e:
        return dict.fromkeys(load.bodies, f"its MJCF file {load.path} could not be read ({e})")
    out, k = {}, 0
    for b in load.bodies:
        try:
            root, names = _signature(raw, cid, b, load.multibody)
        except Exception as e:  # pybullet.error: the body is gone
            out[b] = f"pybullet does not describe it ({e})"
            continue
        for i in range(k, len(models)):
            m = models[i]
            if m.root_name == root and (names is None or [lk.name for lk in m.links[1:]] == names):
                out[b], k = m, i + 1
                break
        else:
            out[b] = f"its links do not match those of any model in {load.path}"
    return out
