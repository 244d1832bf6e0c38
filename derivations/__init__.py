"""Symbolic robot kinematics (SymPy only; this package never prints code).

>>> import derivations
>>> model = derivations.load("planar_2r")
>>> model.task.T
Matrix([[l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]])

The folders are the layers (docs/architecture.md), and imports run one way, from the bottom:
``support/`` (budgets, the cache); the core at this level (``chain``, ``program``,
``chain_program``, ``expressions``, ``model``: the data, ``kinematics``: a chain's frames,
Jacobian and task); then ``formats/`` (TOML and URDF in), ``ik/``, ``rates/``, ``mechanics/``
(dynamics) and ``motion/``; then ``assembly`` (a robot's kernel list) and ``kernelset``; then
``robots/`` (the papers' robots and, in ``robots/extras/``, their papers' own pieces); and this
module's ``load`` on top.

``ROBOTS`` maps each registered robot name to the file that defines it: a
description ``robots/<name>.toml`` (a DH chain, optionally extended by a module
``robots/<name>.py`` with ``extend(model)``), or a module ``robots/<name>.py``
with no description beside it, whose ``build()`` returns the model (for robots
that are not one chain, such as the AVR 3000).  ``load`` also takes the path of
a user's description file.
``KERNEL_SETS`` names the
generated packages that are not robots (time laws, a paper's path), each built
by the module of that name (``load_kernel_set``).
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import time
from pathlib import Path
from typing import Callable

from .support.cache import cached
from .formats.description import read_description
from .formats.shared import Description, DescriptionError, check_task, free_joint_index, task_option
from .kernelset import KernelSet
from .model import IKBranch, RobotModel, SymbolicFunction, TaskError
from .kinematics import build_chain_model
from . import assembly  # installs the kernel assembly the model hands functions(), rates and dynamics to

__all__ = ["ROBOTS", "load", "RobotModel", "SymbolicFunction", "IKBranch", "DescriptionError",
           "UnknownRobotError", "KERNEL_SETS", "KernelSet", "load_kernel_set"]

# Modules that moved into the layer folders (issue #29, docs/architecture.md), under their old
# names: `import derivations.urdf`, `from derivations.velocity import rate_kinematics` and
# `derivations.description.read_description` keep working, and give the very module the new name
# does (so that a test's monkeypatch of the old name patches what the code reads).  Code inside
# derivations/ and codegen/ imports the new names (tests/test_import_layers.py holds it to that).
MOVED = {
    "description": "formats.description", "urdf": "formats.urdf",
    "velocity": "rates.velocity", "damping": "rates.damping", "singular": "rates.singular", "paul": "rates.paul",
    "mobility": "motion.mobility",
    "dynamics": "mechanics.dynamics", "inertia": "mechanics.inertia",
    "budget": "support.budget", "cache": "support.cache",
    "spaces": "robots.extras.spaces", "motor_limits": "robots.extras.motor_limits",
    "tool_configuration": "robots.extras.tool_configuration", "parallel": "robots.extras.parallel",
}


class _MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports ``derivations.<old>`` as the module ``derivations.<MOVED[old]>``."""

    def find_spec(self, fullname, path=None, target=None):
        package, _, old = fullname.rpartition(".")
        if package == __name__ and old in MOVED:
            return importlib.util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec):
        return importlib.import_module(f"{__name__}.{MOVED[spec.name.rpartition('.')[2]]}")

    def exec_module(self, module):
        pass  # the module under its new name has run already


if not any(isinstance(finder, _MovedModules) for finder in sys.meta_path):
    sys.meta_path.append(_MovedModules())


def __getattr__(name):
    if name in MOVED:  # `import derivations; derivations.urdf...`
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

_ROBOT_DIR = Path(__file__).resolve().parent / "robots"

def _registry() -> dict[str, Path]:
    robots = {p.stem: p for p in _ROBOT_DIR.glob("*.toml")}
    for module in _ROBOT_DIR.glob("*.py"):
        if not module.stem.startswith("_") and module.stem not in robots:
            robots[module.stem] = module  # a robot built in Python: the module defines build()
    return dict(sorted(robots.items()))


ROBOTS: dict[str, Path] = _registry()
# Generated packages that are not robots: name -> the module whose kernel_set() builds it.
KERNEL_SETS: dict[str, Path] = {name: Path(__file__).resolve().parent / f"{name}.py"
                                for name in ("trajectory", "scorbot_path")}


class UnknownRobotError(KeyError, ValueError):
    """A robot name that is neither registered nor a description file."""

    def __str__(self):
        return self.args[0]


def load(name: str | Path, *, verbose: bool = False, base: str | None = None, tip: str | None = None,
         snap: bool = True, free_joint: int | str | None = None, dynamics: bool = True, task: str | list[str] | None = None,
         before_ik: Callable[[RobotModel], None] | None = None) -> RobotModel:
    """The symbolic model of a registered robot, or of a description file.

    ``name`` is a registry name (see ``ROBOTS``), the path of a ``.toml``
    description, or the path of a ``.urdf`` file; for a URDF, ``base`` and ``tip``
    name the links the chain runs between and ``snap`` rounds angles and axes
    within ``derivations.formats.urdf.SNAP_TOLERANCE`` of pi/2 multiples and coordinate axes
    to them exactly (``derivations.formats.urdf``).  ``free_joint`` (a number from 1, or a joint's name)
    is the joint a seven-joint arm's ik holds at its argument ``free`` (a description's
    ``free_joint`` otherwise; by default the first that leaves a six-joint arm with a closed
    form).  ``task`` (a list of items, or their names separated by commas: ``"x,y,z,pitch"``) replaces
    the description's task (a URDF's is the pose).  Derivation results are cached on disk
    (``derivations.cache``).  ``dynamics=False`` leaves out the equations of motion of an arm with
    inertial parameters.  ``before_ik(model)`` is called with a description's model, derived afresh
    (not from the cache), before its inverse kinematics is derived: `kinegen generate` starts
    deriving the rates and dynamics beside it there (``codegen.generate.RatesAndMotion``).
    """
    path = _resolve(name)
    if path.suffix == ".py":
        return _load_module(path, verbose)
    if path.suffix == ".urdf":
        from .formats.urdf import read_urdf
        description = read_urdf(path, base=base, tip=tip, snap=snap)
    else:
        description = read_description(path)
    if task is not None:
        def refuse_task(message):
            raise DescriptionError(f"{path}: task: {message}")
        description.task = (task_option(task, refuse_task) if isinstance(task, str) else
                            check_task(list(task) if isinstance(task, tuple) else task, refuse_task))
    if free_joint is not None:
        def refuse(message):
            raise DescriptionError(f"{path}: free joint: {message}")
        description.free_joint = free_joint_index(free_joint, description.joints, refuse)
    if not dynamics:  # kinematics only: no inertials, no gravity parameter
        description.drop_dynamics()
    # The key: the bytes the description was read from (read once: the same the derivation reads),
    # the file's name (the package's source names it), the chain's ends and the held joint.
    text = path.name.encode() + b"\0" + description.inputs + repr((base, tip, snap, dynamics, description.free_joint, description.task)).encode()
    extension = _ROBOT_DIR / f"{description.name}.py" if path.parent == _ROBOT_DIR else None
    start = time.perf_counter()
    try:
        model = cached(f"model-{description.name}", text, lambda: _derive(description, extension, before_ik))
    except TaskError as error:  # a task coordinate the chain does not have: the input's fault
        raise DescriptionError(f"{path}: task {','.join(description.task)}: {error}") from None
    if task is not None and getattr(model, "ik_task_unreachable", False):
        raise DescriptionError(f"{path}: task {','.join(description.task)}: {model.ik_unsupported}")
    if verbose:
        print(f"[derive] {description.name}: {time.perf_counter() - start:.2f} s", file=sys.stderr)
    return model


def _load_module(path: Path, verbose: bool) -> RobotModel:
    module = importlib.import_module(f"derivations.robots.{path.stem}")
    start = time.perf_counter()
    model = cached(f"model-{path.stem}", path.read_bytes(), module.build)
    if verbose:
        print(f"[derive] {path.stem}: {time.perf_counter() - start:.2f} s", file=sys.stderr)
    return model


def _resolve(name: str | Path) -> Path:
    if isinstance(name, str) and name in ROBOTS:
        return ROBOTS[name]
    path = Path(name)
    if path.suffix in (".toml", ".urdf"):
        if not path.is_file():
            raise DescriptionError(f"{path}: no such description file")
        return path
    if path.suffix == ".xacro":
        raise DescriptionError(f"{path}: a xacro file; expand it first (`xacro {path.name} > robot.urdf` with ROS, "
                               f"or `xacrodoc {path.name} -o robot.urdf`), then give the .urdf")
    known = ", ".join(ROBOTS)
    raise UnknownRobotError(f"unknown robot {str(name)!r}; known robots: {known} "
                            "(or give a .toml description or a .urdf file)")


def _derive(description: Description, extension: Path | None, before_ik=None) -> RobotModel:
    limits = [None if j.limits is None else (float(j.limits[0]), float(j.limits[1])) for j in description.joints]
    model = build_chain_model(description.name, description.title, description.source, description.chain(),
                              description.q, description.params, description.task, limits)
    model.notes.update(description.notes)
    model.inertials, model.gravity = tuple(description.inertials), tuple(description.gravity)
    model.actuators = tuple(description.actuators)
    names = [j.name for j in description.joints]
    if all(names) and len(set(names)) == len(names):
        model.joint_names = tuple(names)
    if description.base_link and all(j.link for j in description.joints):
        model.frame_names = (description.base_link, *(j.link for j in description.joints)) + \
            (("tool",) if len(model.frames) > model.n + 1 else ())
    if extension is not None and extension.is_file():
        module = importlib.import_module(f"derivations.robots.{description.name}")
        module.extend(model)
    if not model.ik:  # the papers' robots print their paper's steps; every other arm is decomposed
        from .ik import attach
        if before_ik is not None:
            before_ik(model)
        attach(model, description.free_joint)
    return model


def load_kernel_set(name: str) -> KernelSet:
    """The kernels of a non-robot package (see ``KERNEL_SETS``), cached on disk like a model."""
    if name not in KERNEL_SETS:
        raise UnknownRobotError(f"unknown kernel set {name!r}; known kernel sets: {', '.join(KERNEL_SETS)}")
    module = importlib.import_module(f"derivations.{name}")
    # A kernel set may read robot models (the SCORBOT path does): their descriptions are part of the key.
    content = KERNEL_SETS[name].read_bytes() + b"".join(p.read_bytes() for p in ROBOTS.values())
    return cached(f"kernels-{name}", content, module.kernel_set)
