"""Robot description files (TOML) -> serial-chain models.

The papers' DH robots ship as description files in ``derivations/robots/``, and
a user's robot is described the same way::

    name = "cylindrical_rpp"
    convention = "standard"          # or "modified" (Craig)
    task = ["x", "y", "z"]           # x y z phi pose; default ["pose"]
    [params]                         # defaults in SI; usable in any field below
    d1 = 0.5
    [[joint]]
    type = "R"                       # R (revolute) or P (prismatic)
    a = 0                            # numbers, parameter names, or expressions of them and pi
    alpha = 0
    d = "d1"
    offset = 0                       # added to the joint variable
    limits = [-3.1416, 3.1416]       # optional, rad or m
    [tool]                           # optional fixed transform after the last joint
    xyz = [0, 0, 0.1]
    rpy = [0, 0, 0]
    [base]                           # optional fixed transform before the first joint
    rpy = ["pi", 0, 0]               # (a ceiling mount)

Every error is a :class:`DescriptionError` naming the file, the joint and the
field.
"""
from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path
from typing import Any

import sympy as sp

from ..chain import PRISMATIC, REVOLUTE, Joint, rpy_matrix
from ..expressions import ExpressionError, is_identifier, is_package_name, parse_expression
from .shared import (MAX_DESCRIPTION_BYTES, MAX_JOINTS, Description, DescriptionError, check_task, free_joint_index,
                     read_input, task_option)

__all__ = ["DescriptionError", "Description", "read_description", "parse_description", "free_joint_index",
           "check_task", "task_option", "read_input", "MAX_JOINTS"]

TOP_KEYS = {"name", "title", "source", "convention", "task", "params", "joint", "tool", "base", "notes", "free_joint",
            "gravity"}
# A description may take its chain from a URDF file instead of [[joint]] tables, and add its own
# task, parameters and [tool] / [base] frames (whose values may use the parameters).
# `actuator` over a URDF: a table per joint, keyed by the joint's name or number (see parse_actuators).
URDF_KEYS = {"urdf", "base_link", "tip_link", "snap", "actuator"}
JOINT_KEYS = {"type", "a", "alpha", "d", "theta", "offset", "limits", "name", "inertial", "actuator"}
# A joint's `inertial` table: the link it moves (DH frame k), see docs/dynamics.md; its `actuator`
# table: the drive (derivations.inertia.ACTUATOR_KEYS), see docs/dynamics.md#actuator-models.
INERTIAL_KEYS = {"mass", "com", "inertia"}
FRAME_KEYS = {"xyz", "rpy"}


def read_description(path: str | Path) -> Description:
    """Read and validate a description file."""
    path = Path(path)
    raw = read_input(path, MAX_DESCRIPTION_BYTES, "description")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DescriptionError(f"{path}: not UTF-8 text (byte {exc.start}); a description is a UTF-8 TOML file") from None
    description = parse_description(text, str(path))
    description.inputs = raw + b"\0" + description.inputs  # and the URDF's bytes, for one over a URDF
    return description


def parse_description(text: str, origin: str = "<string>") -> Description:
    """Parse description text; ``origin`` names it in error messages."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DescriptionError(f"{origin}: malformed TOML: {exc}") from None
    except ValueError as exc:  # an integer of more than 4,300 digits (Python's own limit)
        raise DescriptionError(f"{origin}: a number too long to read ({' '.join(str(exc).split()[:12])})") from None
    except RecursionError:  # arrays or inline tables nested thousands deep
        raise DescriptionError(f"{origin}: arrays or tables nested too deep to read (a description nests a few "
                               "levels)") from None
    return _Parser(origin).parse(data)


class _Parser:
    def __init__(self, origin: str):
        self.origin = origin

    def fail(self, where: str, message: str):
        raise DescriptionError(f"{self.origin}: {where}: {message}")

    def parse(self, data: dict[str, Any]) -> Description:
        if "urdf" in data:
            return self.parse_urdf(data)
        unknown = sorted(set(data) - TOP_KEYS)
        if unknown:
            self.fail("top level", f"unknown field {unknown[0]!r} (expected one of {', '.join(sorted(TOP_KEYS))})")
        name = data.get("name")
        if name is None:
            self.fail("top level", "missing field 'name'")
        if not isinstance(name, str) or not is_identifier(name):
            self.fail("field 'name'", f"{name!r} is not a valid identifier "
                      "(ASCII letters, digits and _, not starting with a digit or _, not a reserved word)")
        if not is_package_name(name):
            self.fail("field 'name'", f"{name!r} would shadow the Python module of that name "
                      "(a standard-library or kinegen module) or a C header its C includes; choose another")
        convention = data.get("convention", "standard")
        if convention not in ("standard", "modified"):
            self.fail("field 'convention'", f"expected 'standard' or 'modified', got {convention!r}")
        for key in ("title", "source"):
            if key in data and not isinstance(data[key], str):
                self.fail(f"field {key!r}", "expected a string")

        params = self.parse_params(data.get("params", {}))
        self.defaults = params
        joints_data = data.get("joint")
        if joints_data is None:
            self.fail("top level", "missing [[joint]] tables: a robot needs at least one joint")
        if not isinstance(joints_data, list) or not all(isinstance(j, dict) for j in joints_data):
            self.fail("field 'joint'", "expected an array of tables ([[joint]])")
        if not 1 <= len(joints_data) <= MAX_JOINTS:
            self.fail("field 'joint'", f"{len(joints_data)} joints; a description has 1 to {MAX_JOINTS}")
        q = tuple(sp.Symbol(f"q{i + 1}", real=True) for i in range(len(joints_data)))
        names = {str(s): s for s in params}
        joints = [self.parse_joint(i, j, names) for i, j in enumerate(joints_data)]
        named = [j.name for j in joints if j.name]
        if len(set(named)) != len(named):
            repeated = sorted({n for n in named if named.count(n) > 1})[0]
            self.fail("field 'joint'", f"two joints are named {repeated!r} (a joint's name is its own)")
        tool = self.parse_frame(data.get("tool"), names, "tool")
        base = self.parse_frame(data.get("base"), names, "base")

        task = data.get("task", ["pose"])
        check_task(task, lambda message: self.fail("field 'task'", message))
        notes = data.get("notes", {})
        if not isinstance(notes, dict) or not all(isinstance(v, str) for v in notes.values()):
            self.fail("field 'notes'", "expected a table of strings")
        inertials, gravity = self.parse_dynamics(data, joints_data, params, names)
        actuators = [None if j.get("actuator") is None else
                     self.actuator(f"joint {i + 1}: field 'actuator'", j["actuator"], names, params)
                     for i, j in enumerate(joints_data)]
        if any(actuators) and not inertials:
            self.fail("field 'actuator'", "an actuator without inertial tables: give each joint's `inertial`")
        return Description(
            name=name, title=data.get("title", name), source=data.get("source", ""),
            convention=convention, task=task, params=params, joints=joints, tool=tool,
            notes=dict(notes), q=q, base=base, free_joint=self.free_joint(data, joints),
            inertials=inertials, gravity=gravity, gravity_parameter=self.gravity_parameter,
            actuators=tuple(actuators) if any(actuators) else (),
        )

    def actuator(self, where: str, raw, names, params, given=None):
        """A joint's ``actuator`` table {rotor_inertia, gear_ratio, viscous, coulomb} (each a number,
        parameter or expression; defaults 0, 1, 0, 0, or the fields of ``given``: a URDF's
        ``<dynamics>``), checked at the parameters' defaults (derivations.inertia.check_actuator)."""
        from ..mechanics.inertia import ACTUATOR_KEYS, Actuator, check_actuator
        if not isinstance(raw, dict):
            self.fail(where, "expected a table {rotor_inertia = ..., gear_ratio = ..., viscous = ..., coulomb = ...}")
        unknown = sorted(set(raw) - set(ACTUATOR_KEYS))
        if unknown:
            self.fail(where, f"unknown field {unknown[0]!r} (expected {', '.join(ACTUATOR_KEYS)})")
        given = given or Actuator()
        fields = {key: self.value(f"{where}: {key}", raw[key], names) if key in raw else getattr(given, key)
                  for key in ACTUATOR_KEYS}
        subs = {s: sp.Rational(repr(v)) for s, v in params.items()}
        check_actuator({key: float(sp.sympify(e).xreplace(subs).evalf(30)) for key, e in fields.items()},
                       lambda message: self.fail(where, message))
        return Actuator(**fields)

    def parse_actuators(self, raw, joints, given, names, params) -> tuple:
        """``[actuator.<joint>]`` over a URDF: per joint (its name, or its number from 1) the fields
        that replace or add to what the URDF's ``<dynamics damping friction>`` gave (``given``)."""
        if raw is None:
            return tuple(given)
        if not isinstance(raw, dict):
            self.fail("field 'actuator'", "expected tables [actuator.<joint name or number>]")
        actuators = list(given) or [None] * len(joints)
        labels = [j.name for j in joints]
        for key, table in raw.items():
            if key in labels:
                k = labels.index(key)
            elif key.isdigit() and 1 <= int(key) <= len(joints):
                k = int(key) - 1
            else:
                self.fail(f"field 'actuator.{key}'", f"no moving joint {key!r} on the chain (expected a joint's name, "
                          f"{', '.join(labels)}, or its number from 1 to {len(joints)})")
            actuators[k] = self.actuator(f"field 'actuator.{key}'", table, names, params, actuators[k])
        return tuple(actuators) if any(actuators) else ()

    def parse_dynamics(self, data, joints_data, params, names):
        """Each joint's ``inertial`` table (all joints or none) and ``gravity`` (a list of three
        values in the base frame; default ``[0, 0, "-gravity"]`` with the parameter ``gravity`` =
        9.81 added).  ``params`` gains that parameter; each link is checked physical at the defaults."""
        self.gravity_parameter = None
        given = [j.get("inertial") for j in joints_data]
        if all(g is None for g in given):
            if "gravity" in data:
                self.fail("field 'gravity'", "gravity without inertial tables: give each joint's `inertial`")
            return (), ()
        from ..mechanics.inertia import Inertial, check_physical
        inertials = []
        for i, raw in enumerate(given):
            where = f"joint {i + 1}: field 'inertial'"
            if raw is None:
                self.fail(where, "missing: give every joint's link an inertial table, or none")
            if not isinstance(raw, dict):
                self.fail(where, "expected a table {mass = ..., com = [x, y, z], inertia = [ixx, ixy, ixz, iyy, iyz, izz]}")
            unknown = sorted(set(raw) - INERTIAL_KEYS)
            if unknown:
                self.fail(where, f"unknown field {unknown[0]!r} (expected mass, com, inertia)")
            if "mass" not in raw:
                self.fail(where, "missing field 'mass'")
            com, inertia = raw.get("com", [0, 0, 0]), raw.get("inertia", [0] * 6)
            if not isinstance(com, list) or len(com) != 3:
                self.fail(f"{where}: com", "expected a list of three values (m, in the link's frame)")
            if not isinstance(inertia, list) or len(inertia) != 6:
                self.fail(f"{where}: inertia", "expected [ixx, ixy, ixz, iyy, iyz, izz] (kg m^2, about the centre of mass)")
            inertial = Inertial(self.value(f"{where}: mass", raw["mass"], names),
                                tuple(self.value(f"{where}: com", v, names) for v in com),
                                tuple(self.value(f"{where}: inertia", v, names) for v in inertia))
            mass, centre, tensor = inertial.numbers(params)
            check_physical(mass, centre, tensor, lambda message: self.fail(where, message))
            inertials.append(inertial)
        if "gravity" in data:
            raw = data["gravity"]
            if not isinstance(raw, list) or len(raw) != 3:
                self.fail("field 'gravity'", "expected a list of three values (m/s^2, in the base frame)")
            gravity = tuple(self.value("field 'gravity'", v, names) for v in raw)
        else:
            symbol = names.get("gravity")
            if symbol is None:
                symbol = sp.Symbol("gravity", real=True)
                params[symbol] = 9.81
                names["gravity"] = symbol
                self.gravity_parameter = symbol
            gravity = (sp.S.Zero, sp.S.Zero, -symbol)
        return tuple(inertials), gravity

    def free_joint(self, data, joints) -> int | None:
        """``free_joint``: the joint a seven-joint arm's ik holds, by number (1-based) or by name."""
        if "free_joint" not in data:
            return None
        return free_joint_index(data["free_joint"], joints, lambda message: self.fail("field 'free_joint'", message))

    def parse_urdf(self, data: dict[str, Any]) -> Description:
        """``urdf = "arm.urdf"`` (relative to this file) with optional ``base_link``, ``tip_link``,
        ``snap``, and this file's own name, title, task, params, [tool] and [base]."""
        allowed = (TOP_KEYS - {"joint", "convention"}) | URDF_KEYS
        unknown = sorted(set(data) - allowed)
        if unknown:
            self.fail("top level", f"unknown field {unknown[0]!r} with 'urdf' (expected one of {', '.join(sorted(allowed))}; "
                      "the joints come from the URDF)")
        for key in ("urdf", "base_link", "tip_link", "name", "title", "source"):
            if key in data and not isinstance(data[key], str):
                self.fail(f"field {key!r}", "expected a string")
        if "snap" in data and not isinstance(data["snap"], bool):
            self.fail("field 'snap'", "expected true or false")
        from .urdf import read_urdf
        path = Path(self.origin).parent / data["urdf"]
        if "\0" in data["urdf"]:
            self.fail("field 'urdf'", "a path with a NUL byte")
        description = read_urdf(path, base=data.get("base_link"), tip=data.get("tip_link"),
                                snap=data.get("snap", True))
        name = data.get("name", description.name)
        if not is_package_name(name):
            self.fail("field 'name'", f"{name!r} is not a valid identifier or would shadow a Python module "
                      "or a C header")
        params = self.parse_params(data.get("params", {}))
        for symbol, value in description.params.items():  # the URDF's own (gravity), unless redefined
            if str(symbol) not in {str(p) for p in params}:
                params[symbol] = value
        self.defaults = params
        names = {str(p): p for p in params}
        gravity, added = description.gravity, description.gravity_parameter
        if added is not None and str(added) in data.get("params", {}):
            added = None  # this file defines the parameter itself
        if "gravity" in data:
            if not description.inertials:
                self.fail("field 'gravity'", "gravity for a URDF whose chain has no <inertial>")
            raw = data["gravity"]
            if not isinstance(raw, list) or len(raw) != 3:
                self.fail("field 'gravity'", "expected a list of three values (m/s^2, in the base frame)")
            gravity = tuple(self.value("field 'gravity'", v, names) for v in raw)
        if "actuator" in data and not description.inertials:
            self.fail("field 'actuator'", "an actuator for a URDF whose chain has no <inertial>")
        actuators = self.parse_actuators(data.get("actuator"), description.joints, description.actuators, names, params)
        task = data.get("task", ["pose"])
        check_task(task, lambda message: self.fail("field 'task'", message))
        notes = data.get("notes", {})
        if not isinstance(notes, dict) or not all(isinstance(v, str) for v in notes.values()):
            self.fail("field 'notes'", "expected a table of strings")
        return Description(
            name=name, title=data.get("title", description.title), source=data.get("source", description.source),
            convention="urdf", task=task, params=params, joints=description.joints,
            tool=self.parse_frame(data.get("tool"), names, "tool"), notes={**description.notes, **notes},
            q=description.q, base=self.parse_frame(data.get("base"), names, "base"), inputs=description.inputs,
            base_link=description.base_link, free_joint=self.free_joint(data, description.joints),
            inertials=description.inertials, gravity=gravity, gravity_parameter=added,
            actuators=actuators)

    def parse_params(self, raw) -> dict[sp.Symbol, float]:
        if not isinstance(raw, dict):
            self.fail("field 'params'", "expected a table of name = number")
        params: dict[sp.Symbol, float] = {}
        for key, value in raw.items():
            where = f"params: {key!r}"
            # q1.., qd1.., qdd1.., xd_*, xdd_*, twist_* name the kernels' arguments (derivations/rates/velocity.py).
            if not is_identifier(key) or re.fullmatch(r"qd{0,2}\d+|tau\d+|(xdd?|twist|wrench)_\w+", key):
                self.fail(where, "not a valid parameter name (an identifier that is not reserved and not q1, q2, ..., "
                          "qd1, qdd1, tau1, ..., or xd_*, xdd_*, twist_*, wrench_*)")
            self.defaults = {}
            expr = self.value(where, value, {})  # parsed, and checked finite and real
            params[sp.Symbol(key, real=True)] = float(expr)
        return params

    def value(self, where: str, raw, names) -> sp.Expr:
        """A field's exact value, which must be a finite real number at the parameters' defaults."""
        try:
            expr = parse_expression(raw, names)
        except ExpressionError as exc:
            self.fail(where, str(exc))
        defaults = {symbol: sp.Rational(repr(value)) for symbol, value in getattr(self, "defaults", {}).items()}
        try:
            number = complex(sp.sympify(expr).xreplace(defaults).evalf(30))
        except (TypeError, ValueError, OverflowError, ZeroDivisionError):
            number = complex("nan")
        if not (math.isfinite(number.real) and number.imag == 0 and abs(number.real) <= 1e300):
            self.fail(where, f"{raw!r} is not a finite real number at the parameters' defaults "
                      f"({'complex' if number.imag and math.isfinite(number.imag) else 'infinite or undefined' if not math.isfinite(number.real) else 'beyond 1e300'})")
        return expr

    def parse_joint(self, i: int, raw: dict, names) -> Joint:
        label = f"joint {i + 1}" + (f" ({raw['name']})" if isinstance(raw.get("name"), str) else "")
        unknown = sorted(set(raw) - JOINT_KEYS)
        if unknown:
            self.fail(label, f"unknown field {unknown[0]!r} (expected {', '.join(sorted(JOINT_KEYS - {'name'}))})")
        if "type" not in raw:
            self.fail(label, "missing field 'type' (R for revolute or P for prismatic)")
        jtype = raw["type"]
        if jtype not in (REVOLUTE, PRISMATIC):
            self.fail(f"{label}: field 'type'", f"unknown joint type {jtype!r} (expected 'R' or 'P')")
        if jtype == REVOLUTE and "theta" in raw:
            self.fail(f"{label}: field 'theta'", "theta is the joint variable of a revolute joint; use 'offset'")
        if jtype == PRISMATIC and "d" in raw:
            self.fail(f"{label}: field 'd'", "d is the joint variable of a prismatic joint; use 'offset'")
        fields = {}
        for key in ("a", "alpha", "d", "theta", "offset"):
            fields[key] = self.value(f"{label}: field {key!r}", raw.get(key, 0), names)
        limits = None
        if "limits" in raw:
            lim = raw["limits"]
            if not isinstance(lim, list) or len(lim) != 2:
                self.fail(f"{label}: field 'limits'", "expected [low, high]")
            low, high = (self.value(f"{label}: field 'limits'", v, {}) for v in lim)
            if not float(low) < float(high):
                self.fail(f"{label}: field 'limits'", f"low {float(low)} must be below high {float(high)}")
            limits = (low, high)
        name = raw.get("name", "")
        if not isinstance(name, str) or len(name) > 200 or not name.isprintable():
            self.fail(f"{label}: field 'name'", "expected a printable string of at most 200 characters "
                      "(the joint's name, as a ROS joint_states message gives it)")
        return Joint(type=jtype, limits=limits, name=name, **fields)

    def parse_frame(self, raw, names, which: str) -> sp.Matrix:
        """A fixed transform ``[tool]`` or ``[base]``: ``xyz`` (m) and ``rpy`` (rad; fixed-axis
        roll, pitch, yaw: ``Rz(yaw) Ry(pitch) Rx(roll)``), each a list of three values."""
        if raw is None:
            return sp.eye(4)
        if not isinstance(raw, dict):
            self.fail(f"field {which!r}", "expected a table with xyz and rpy")
        unknown = sorted(set(raw) - FRAME_KEYS)
        if unknown:
            self.fail(which, f"unknown field {unknown[0]!r} (expected xyz, rpy)")
        vectors = {}
        for key in ("xyz", "rpy"):
            v = raw.get(key, [0, 0, 0])
            if not isinstance(v, list) or len(v) != 3:
                self.fail(f"{which}: field {key!r}", "expected a list of three values")
            vectors[key] = [self.value(f"{which}: field {key!r}", e, names) for e in v]
        transform = sp.eye(4)
        transform[:3, :3] = rpy_matrix(*vectors["rpy"])
        transform[:3, 3] = sp.Matrix(vectors["xyz"])
        return transform
