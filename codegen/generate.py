"""Writing ``generated/``: render every backend for every robot, deterministically.

``render_tree`` returns the whole tree as {relative path: text}; ``write_tree``
writes it (each file atomically, stale generated files removed) and
``stale_files`` lists what differs from what is on disk, for ``make check``.
"""
from __future__ import annotations

import concurrent.futures
import contextlib
import errno
import hashlib
import math
import os
import pickle
import re
import shutil
import signal
import sys
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np
import sympy as sp

import derivations
from derivations.support import pickling
from derivations.support.budget import degraded, stage as budget_stage
from derivations.formats.description import read_description
from derivations.ik import UNIT_SNAP
from derivations.assembly import kinematics_kernels
from derivations.ik.general_6r import equations_function
from derivations.kernelset import KernelSet
from derivations.model import POSE_NAMES, REVOLUTE, RobotModel
from derivations.rates.singular import jacobian_determinant

from .backends import (TEMPLATES, adopt_templates, c_backend, compile_templates, float_literal, latex_backend,
                       numpy_backend)
from .kernels import STATUS_CODES, PreparedFunction, prepare
from .stages import stage

__all__ = ["REPO", "GENERATED", "render_robot", "render_tree", "write_tree", "write_package", "stale_files",
           "robot_context", "OutputExistsError"]

REPO = Path(__file__).resolve().parent.parent
GENERATED = REPO / "generated"
BACKENDS = {"numpy": numpy_backend, "c": c_backend}
# Files that generation owns in a robot folder (anything else there is left alone).
OWNED_SUFFIXES = (".py", ".h", ".c", ".tex", ".toml", ".md")
# What makes a package folder installable on its own (`pip install ./<folder>`) and says how to use it.
PACKAGING = (("package_pyproject.toml.j2", "pyproject.toml"), ("package_setup.py.j2", "setup.py"),
             ("package_readme.md.j2", "README.md"))
# A pose given to ik whose rotation R has max|R^T R - I| above this, or det R < 0, is refused.
RIGID_TOLERANCE = "1e-09"


def safe_text(text: str) -> str:
    """Free text (a title, a citation, a file name) made safe inside C comments and Python docstrings.

    Control characters become spaces, and the sequences that would end a comment
    or a docstring (star-slash, triple quotes, backslashes) are broken up.
    """
    text = "".join(ch if ch.isprintable() else " " for ch in str(text))
    for bad, good in (("\\", "/"), ('"""', "'''"), ("*/", "* /"), ("/*", "/ *")):
        text = text.replace(bad, good)
    return text


# How much of a text a message echoes (a name, a path, a line of a file): a 9 MiB joint name
# must not become a 9 MB error line.
ECHO_LIMIT = 300
# Characters that would move or hide text on a terminal: the bidirectional overrides and isolates.
_BIDI = frozenset("\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069\u200e\u200f")


def terminal_text(text: str, limit: int = ECHO_LIMIT) -> str:
    """``text`` as a terminal may show it: control characters (a newline that would forge a second
    line) and bidirectional overrides written as escapes, and at most ``limit`` characters kept."""
    text = str(text)
    shown = "".join(ch.encode("unicode_escape").decode("ascii") if (not ch.isprintable() and ch != " ")
                    or ch in _BIDI else ch for ch in text[:limit])
    return shown + (f"... ({len(text) - limit} more characters)" if len(text) > limit else "")


def describe_origin(model: RobotModel, description: Path | None) -> str:
    if description is None:
        return f"the derivations model {model.name!r}"
    digest = hashlib.sha256(description.read_bytes()).hexdigest()[:16]
    try:
        shown = description.resolve().relative_to(REPO).as_posix()
    except ValueError:
        shown = description.name
    return safe_text(f"{shown} (sha256 {digest})")


# The blocked (and, with -DKINEGEN_SIMD, vectorised) batch layout is written for kernels of at
# most this many operations after CSE; a larger one loops over its single point in every layout.
# Vectorising a long straight-line block is most of a compile (a Franka Panda's six rate
# kernels of 2,100-5,900 operations: 53 s of gcc -O2 in the SIMD layout, against 8 s plain),
# for kernels whose time is arithmetic rather than sines and cosines.  The papers' robots
# stay under it (the largest, the PUMA's task_acceleration: 1,007).  2,200 rather than 2,000: the
# xArm 7's forward_dynamics (2,124 operations) looped one state at a time, 436 ns a state against
# 128 ns blocked (issue #30's target: 300); the portable build compiles the plain layout only.
BLOCKED_MAX_OPS = 2200


def template_function(prepared: PreparedFunction) -> dict:
    """What the templates need of one kernel."""
    # The inverse kinematics kernel takes NaN and inf (valid says there is no answer), returns
    # the number of valid branches in C and marks a branch invalid where its joints are not finite.
    is_ik = prepared.name == "ik"
    outputs = []
    for out in prepared.outputs:
        outputs.append({
            "name": out.name, "shape": tuple(out.shape), "dtype": out.dtype, "size": out.size,
            "flat": list(enumerate(out.entries)),
            "constant": {k for k, e in enumerate(out.entries) if not getattr(e, "free_symbols", None)},
        })
    # Each argument as (name, symbol names, doc, storage): the storage name holds the
    # array where one of its own symbols takes the argument's name (ik's x holds x, y, ...).
    arguments = tuple((name, symbols, doc, f"_{name}" if name in symbols else name)
                      for name, symbols, doc in prepared.arguments)
    staged = stage(prepared)
    for out, entries in zip(outputs, staged.outputs):
        out["staged"] = list(enumerate(entries))
    # Every output of more than one entry goes the same way: GCC 12 left the whole loop of a kernel
    # that stores several doubles per item unvectorised ("no vectype" for its first load), and the
    # batched inverse_dynamics of the Panda (7 per item) took 134 ns per state instead of 41, the
    # Z1's (6) 103 instead of 32 (each batch function alone, gcc 12 -O3 -march=native).
    block_outputs = [o.name for o in prepared.outputs if o.dtype == "float" and (is_ik or o.size > 1)]
    stream_outputs = [o.name for o in prepared.outputs if o.dtype == "float" and o.size % 2 == 0 and not is_ik]
    arguments_used = prepared.arguments_used  # a walk over every expression: once
    inputs = {s for a in prepared.arguments for s in a[1]} & arguments_used
    per_item = len(inputs) + len(staged.arrays) + sum(o.size for o in prepared.outputs
                                                      if o.name in block_outputs or o.name in stream_outputs)
    block = 64  # items per block of the batched C, halved while its arrays would pass 32 KiB of stack
    while block > 8 and 8 * block * per_item > 32768:
        block //= 2
    return {
        "block": block,
        "blocked": prepared.operations <= BLOCKED_MAX_OPS,
        "prologue": staged.prologue,
        # Outputs the blocked C writes per block, one array per entry, then copies out item by
        # item: GCC 12 does not vectorise a loop that stores ik's 48 joint values per item, nor
        # one that stores a few values per item (see block_outputs).
        "block_outputs": block_outputs,
        # Outputs that can be streamed out in pairs of doubles (16-byte aligned rows: an even
        # size); not ik's, whose checks read the joint values straight back.
        "stream_outputs": stream_outputs,
        "stream_size": sum(o.size for o in prepared.outputs if o.dtype == "float" and o.size % 2 == 0),
        "stages": [{"body": [(n, e, n in staged.arrays) for n, e in s.body], "calls": s.calls,
                    "angles": _angles(s.calls), "groups": _call_groups(s.calls)} for s in staged.stages],
        "arrays": staged.arrays,
        "indexed": staged.arrays | inputs,
        "name": prepared.name, "doc": prepared.doc, "arguments": arguments,
        "params_used": prepared.params_used, "arguments_used": arguments_used,
        "outputs": outputs, "operations": prepared.operations, "checks": prepared.checks, "is_ik": is_ik,
        "solve": None,
        # Temporaries holding a truth value (relations are Boolean but not is_Boolean in SymPy).
        "boolean_temporaries": frozenset(name for name, expr in prepared.temporaries
                                         if isinstance(expr, sp.logic.boolalg.Boolean)),
    }


def _call_groups(calls) -> list[dict]:
    """A stage's calls other than sin and cos, by function, each with its SymPy form (for numpy)."""
    functions = {"atan2": sp.atan2, "acos": sp.acos, "asin": sp.asin}
    groups: dict[str, list] = {}
    for c in calls:
        if c.function in functions:
            expr = functions[c.function](*(sp.Symbol(a, real=True) for a in c.arguments))
            groups.setdefault(c.function, []).append({"name": c.name, "arguments": c.arguments, "expr": expr})
    return [{"function": f, "calls": members} for f, members in groups.items()]


def _angles(calls) -> list[dict]:
    """The sine and cosine variables wanted of each angle of a stage (None where not wanted)."""
    angles: dict[str, dict] = {}
    for c in calls:
        if c.function not in ("sin", "cos"):
            continue
        entry = angles.setdefault(c.argument, {"angle": c.argument, "index": c.name[2:], "sin": None, "cos": None})
        entry[c.function] = c.name
    return list(angles.values())


def entry_points(model: RobotModel) -> list[dict]:
    """The C entry points of ``model`` as a driver calling them needs them (name, arguments,
    outputs, whether it has checks): robot_context's ``functions`` without their CSE, which is
    most of a render (16 s for the PUMA), for `kinegen sanitize` and its tests."""
    arguments_of: dict[str, tuple] = {}
    points = []
    for function in model.functions():
        if function.solve is None:
            arguments = tuple((a.name, tuple(str(s) for s in a.symbols), a.doc) for a in function.arguments)
            arguments_of[function.name] = arguments
        else:
            arguments = arguments_of[function.solve.system]
        outputs = [{"name": out.name, "dtype": out.dtype, "size": int(np.prod(out.shape))}
                   for out in function.outputs]
        # one check per requirement (kernels._stage_checks); a kernel solved at run time has none
        checks = tuple(function.requires) if function.solve is None else ()
        points.append({"name": function.name, "arguments": arguments, "outputs": outputs, "checks": checks})
    return points


def solved_function(function, system: dict) -> dict:
    """What the templates need of a kernel solved at run time (``function.solve``): its
    public outputs, and the kernel ``system`` (already prepared) that forms its linear system."""
    solve = function.solve
    outputs = [{"name": out.name, "shape": tuple(out.shape), "dtype": out.dtype, "size": int(np.prod(out.shape)),
                "flat": [], "staged": [], "constant": set()} for out in function.outputs]
    return {
        "name": function.name, "doc": function.doc, "arguments": system["arguments"],
        "params_used": system["params_used"], "arguments_used": system["arguments_used"],
        "outputs": outputs, "operations": system["operations"], "checks": (), "is_ik": False,
        "solve": {"system": solve.system, "rows": solve.rows, "cols": solve.cols, "kind": solve.kind,
                  "has_rhs": solve.kind == "solution", "cond_limit": float_literal(solve.COND_LIMIT),
                  "damping": float_literal(solve.DAMPING)},
        "prologue": [], "stages": [], "arrays": set(), "indexed": set(), "block": 1, "blocked": False,
        "block_outputs": [], "stream_outputs": [], "stream_size": 0, "boolean_temporaries": frozenset(),
    }


# The kernels robot_context prepares, read by its worker processes (inherited when they fork).
_PREPARING: tuple = ()


def _prepare_one(index: int) -> tuple[dict, int, float, dict | None]:
    """(template dict, operations, seconds, printed) of kernel ``index`` of :data:`_PREPARING`;
    ``printed``: the printers' memos for its expressions (:func:`print_ahead`) in a worker process."""
    function, param_names, ahead = _PREPARING[0][index], _PREPARING[1], _PREPARING[2]
    start = time.perf_counter()
    prepared = prepare(function, param_names)
    context = template_function(prepared)
    return context, prepared.operations, time.perf_counter() - start, print_ahead(context) if ahead else None


def _prepare_packed(index: int) -> bytes:
    """:func:`_prepare_one` in a worker process, pickled by :func:`derivations.support.pickling.dumps`
    (the parent loads the expressions as they are, without SymPy evaluating them again)."""
    return pickling.dumps(_prepare_one(index))


def print_ahead(function: dict) -> dict:
    """The numpy and C printers' memos (their ``memo`` arguments) for the expressions the templates
    print of one kernel (``function``, a :func:`template_function` dict), as a worker process of
    :func:`prepared_functions` fills them: printing is a third of a render, and is per expression.
    An expression the templates print that is missing here is printed by the parent as before."""
    numpy_printer = numpy_backend.NumpyKernelPrinter()
    c_printer = c_backend.CKernelPrinter()
    # the indexed printer writes the blocked layout only (robot.c.j2's staged_batch)
    batch_printer = c_printer.indexed(function["indexed"]) if function["blocked"] and not function["checks"] else None
    for check in function["checks"]:
        for _, expr in check.temporaries:
            numpy_printer.doprint(expr), c_printer.doprint(expr)
        numpy_printer.doprint(check.condition), c_printer.doprint(check.condition)
    for _, expr in function["prologue"]:
        numpy_printer.doprint(expr), c_printer.doprint(expr)
    staged = [expr for s in function["stages"] for _, expr, _ in s["body"]]
    staged += [expr for out in function["outputs"] for index, expr in out["staged"] if index not in out["constant"]]
    for expr in staged:
        numpy_printer.doprint(expr), c_printer.doprint(expr)
        if batch_printer is not None:
            batch_printer.doprint(expr)
    for s in function["stages"]:
        for group in s["groups"]:
            for call in group["calls"]:
                numpy_printer.doprint(call["expr"])
    return {"numpy": numpy_printer._memo, "c": c_printer._memo}


def _worker_signals() -> None:
    """A worker's signals: the parent's handlers (kinegen's SIGTERM as SystemExit, the budget's
    alarm) are not the worker's.  SIGTERM (``Pool.terminate``) ends it at once, as the default does,
    rather than unwinding the parent's stack that the fork copied (a worker that did so could block
    on a lock held at the fork, and the parent waited for it for ever); Ctrl-C is the parent's."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGALRM, signal.SIG_IGN)
    signal.signal(signal.SIGPROF, signal.SIG_IGN)


def _prepare_jobs(count: int) -> int:
    """Worker processes for one robot's kernels: :func:`default_jobs`, but one inside a worker
    process already (render_tree's), where fork is not the start method at hand, and for few kernels."""
    import multiprocessing
    if count < 4 or multiprocessing.current_process().daemon or "fork" not in multiprocessing.get_all_start_methods():
        return 1
    return min(default_jobs(), count)


def prepared_functions(functions, param_names: tuple, jobs: int | None = None,
                       early: "EarlyKernels | None" = None, ready: dict | None = None,
                       ahead: bool = False) -> list[tuple[dict, int, float]]:
    """:func:`_prepare_one` of every kernel in ``functions`` (those solved at run time excluded), in
    ``jobs`` forked processes (default :func:`_prepare_jobs`), the largest first.

    Each kernel's CSE and staging is independent of the others' and of the process it runs in (the
    text is the same in one process or several, tested), and it is most of a render: an arm with
    its dynamics has two kernels (coriolis, regressor) of about a second each.  A budget that runs
    out in the parent (its alarm) ends the workers with it.  ``early``: kernels a process of their
    own has been preparing since before the others existed (:class:`EarlyKernels`), taken from it;
    ``ready``: {name: result} of kernels prepared already (:class:`RatesAndMotion`).  ``ahead``: print
    ahead even in this process (its results go to another)."""
    global _PREPARING
    ready = ready or {}
    own = [i for i, f in enumerate(functions) if f.solve is None]
    rest = [i for i in own if (early is None or functions[i].name not in early.names)
            and functions[i].name not in ready]
    jobs = _prepare_jobs(len(rest)) if jobs is None else jobs
    _PREPARING = (functions, param_names, jobs > 1 or early is not None or bool(ready) or ahead)
    try:
        if jobs <= 1:
            results = {i: _prepare_one(i) for i in rest}
        else:
            import multiprocessing
            order = sorted(rest, key=lambda i: -len(functions[i].definitions))
            pool = multiprocessing.get_context("fork").Pool(jobs, initializer=_worker_signals)
            try:
                packed = dict(zip(order, pool.imap(_prepare_packed, order, chunksize=1)))
            except BaseException:  # a budget, Ctrl-C or SIGTERM in the parent: the workers go with it
                pool.terminate()
                raise
            pool.close()  # done: the workers leave on their own (no signal sent to them)
            pool.join()
            results = {i: pickle.loads(data) for i, data in packed.items()}  # our own workers' bytes
        results.update((i, ready[functions[i].name]) for i in own if functions[i].name in ready)
        if early is not None:
            done = early.result()
            results.update((i, done[functions[i].name]) for i in own if i not in results)
        return [results[i] for i in own]
    finally:
        _PREPARING = ()


class Forked:
    """``function()`` run in a forked child process, its value read back through a pipe (pickled):
    work that can go on beside the parent's, from what the parent holds in memory at the fork.
    :meth:`result` waits for it (and raises what it raised); :meth:`cancel` ends it, and with
    ``group`` the processes it started too (the child leads a process group of its own)."""

    def __init__(self, function, group: bool = False):
        read, write = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child: never returns into the parent's stack
            status = 1
            try:
                os.close(read)
                if group:
                    with contextlib.suppress(OSError):
                        os.setpgid(0, 0)
                _worker_signals()
                try:
                    payload = pickling.dumps((True, function()))
                except BaseException as exc:  # handed to the parent, as multiprocessing does
                    try:
                        payload = pickle.dumps((False, exc), protocol=pickle.HIGHEST_PROTOCOL)
                    except Exception:
                        payload = pickle.dumps((False, RuntimeError("".join(traceback.format_exception(exc)))))
                with os.fdopen(write, "wb") as pipe:
                    pipe.write(payload)
                status = 0
            finally:
                os._exit(status)
        os.close(write)
        if group:  # (both sides set it: whichever runs first, the group exists before cancel)
            with contextlib.suppress(OSError):
                os.setpgid(pid, pid)
        self._pid, self._read, self._group = pid, read, group

    def result(self):
        with os.fdopen(self._read, "rb") as pipe:
            data = pipe.read()
        _, status = os.waitpid(self._pid, 0)
        self._pid = None
        if not data:
            raise RuntimeError(f"a worker process ended without its result (wait status {status})")
        ok, value = pickle.loads(data)  # our own child's bytes, through a pipe only it and we hold
        if not ok:
            raise value
        return value

    def cancel(self) -> None:
        if self._pid is None:
            return
        with contextlib.suppress(ProcessLookupError):
            if self._group:  # the child and the worker processes it started
                os.killpg(self._pid, signal.SIGTERM)
            else:
                os.kill(self._pid, signal.SIGTERM)
        os.waitpid(self._pid, 0)
        os.close(self._read)
        self._pid = None


class _SideJob:
    """A :class:`Forked` job of this process's own, taken once (:meth:`_take`) or cancelled; nothing
    to take or cancel where none was started."""

    _job: "Forked | None" = None

    @property
    def pending(self) -> bool:
        return self._job is not None

    def _take(self):
        job, self._job = self._job, None
        return None if job is None else job.result()

    def cancel(self) -> None:
        job, self._job = self._job, None
        if job is not None:
            job.cancel()


def _prepared_by_name(functions, param_names: tuple, jobs: int | None = None) -> dict:
    """{kernel name: :func:`prepared_functions`' result} of ``functions``, printed ahead (for
    another process: :class:`EarlyKernels`, :class:`RatesAndMotion`)."""
    own = [f.name for f in functions if f.solve is None]
    return dict(zip(own, prepared_functions(functions, param_names, jobs, ahead=True)))


class EarlyKernels(_SideJob):
    """The kernels that need neither the rate kinematics nor the dynamics (``position_functions``),
    prepared (:func:`_prepare_one`, printed ahead) in a forked process while the parent derives
    those: on two cores that derivation (a KR 210's: 1.6 s) no longer leaves one core idle."""

    def __init__(self, functions, param_names: tuple):
        self.names = frozenset(f.name for f in functions if f.solve is None)
        self._job = Forked(lambda: _prepared_by_name(functions, param_names, jobs=1))

    def result(self) -> dict:
        return self._take()


class TemplatesAhead(_SideJob):
    """The templates compiled (:func:`codegen.backends.compile_templates`) in a forked process
    while this one derives an arm, whose first seconds (the model and its ik) leave the second
    core idle: the render then starts with them compiled (:meth:`adopt`).  Without processes to
    spare, nothing is forked and the templates compile when first used, as before."""

    def __init__(self):
        self._job = Forked(compile_templates) if _prepare_jobs(4) > 1 else None

    def adopt(self) -> None:
        code = self._take()
        if code is not None:
            adopt_templates(code)


def robot_context(model: RobotModel, origin: str, verbose: bool = False, jobs: int | None = None,
                  functions=None, early: EarlyKernels | None = None, ready: dict | None = None) -> dict:
    """What the templates need of ``model``: every kernel prepared (``functions``, default
    ``model.functions()``; ``early``, ``ready``: those of them prepared already, as
    :func:`prepared_functions` takes them), its constants and names."""
    param_names = tuple(str(s) for s in model.params)
    model_functions = list(model.functions()) if functions is None else list(functions)
    prepared = iter(prepared_functions(model_functions, param_names, jobs, early, ready))
    functions = []
    by_name = {}
    printed: dict = {"numpy": {}, "c": {}}
    for function in model_functions:
        if function.solve is not None:
            functions.append(solved_function(function, by_name[function.solve.system]))
            continue
        context, operations, seconds, ahead = next(prepared)
        for backend, memo in (ahead or {}).items():
            printed[backend].update(memo)
        functions.append(context)
        by_name[function.name] = functions[-1]
        if verbose:
            print(f"[cse] {model.name}.{function.name}: {operations} ops, {seconds:.2f} s", file=sys.stderr)
    defaults = {s: sp.Rational(v) for s, v in model.params.items()}
    constants = [(name, float_literal(sp.sympify(value).xreplace(defaults).evalf(30)))
                 for name, value in getattr(model, "constants", {}).items()]
    limits, joint_limits = [], []
    for i, lim in enumerate(model.limits):
        limits.append("None" if lim is None else f"({float_literal(lim[0])}, {float_literal(lim[1])})")
        if lim is not None:
            joint_limits.append((i, float_literal(lim[0]), float_literal(lim[1]),
                                 model.joint_types[i] == REVOLUTE))
    return {
        "name": model.name, "title": safe_text(model.title), "source": safe_text(model.source), "origin": origin,
        "joints": list(getattr(model, "joint_labels", ())), "joint_types": list(model.joint_types),
        "frame_names": list(getattr(model, "frame_labels", ())),
        "ik_method": ik_method(model), "seeded_ik": seeded_ik(model), "seed_count": SEED_COUNT,
        "general_6r": general_6r(model), "general_6r_slots": GENERAL_6R_SLOTS, "general_6r_circle": GENERAL_6R_CIRCLE,
        "ik_unsupported": safe_text(getattr(model, "ik_unsupported", "")),
        "task": list(model.task_names), "branches": [b.name for b in model.ik],
        "ik_ranges": safe_text(getattr(model, "ik_ranges", "")),  # a kernel set has no ik
        "params": [(str(s), float_literal(v)) for s, v in model.params.items()],
        "limits": limits, "functions": functions, "constants": constants,
        # {space: ((low, high), ...)} of a model with coordinate spaces (SPACE_LIMITS)
        "space_limits": [(space, [(float_literal(low), float_literal(high)) for low, high in ranges])
                         for space, ranges in getattr(model, "space_limits", {}).items()],
        "status_codes": list(STATUS_CODES.items()) if any(f["checks"] for f in functions) else [],
        # (joint index, low, high, revolute) of each limited joint, for within_limits.
        "joint_limits": joint_limits,
        "unlimited_joints": [i for i, lim in enumerate(model.limits) if lim is None],
        # A pose task (x, y, z, r11 .. r33): ik also takes (..., 4, 4) and checks the rotation.
        "pose_task": tuple(model.task_names) == POSE_NAMES,
        "rigid_tolerance": RIGID_TOLERANCE,
        "unit_snap": float_literal(UNIT_SNAP),
        "blocked_max_ops": f"{BLOCKED_MAX_OPS:,}",
        # what worker processes printed ahead, for the backends' printers (print_ahead)
        "printed": printed,
    }


# The seeds of ik for an arm with no closed form (the runtime's seeds(): a Kronecker sequence in the
# joint limits): each gives at most one solution; a 6R has at most 16.
SEED_COUNT = 16
# The answers of a general 6R's ik: at most 16 real solutions (Raghavan and Roth 1993).
GENERAL_6R_SLOTS = 16


def _circle(count: int) -> tuple:
    """cos and sin of 2 pi k / count, k = 0 .. count - 1, as C literals (17 digits)."""
    return (tuple(f"{math.cos(2 * math.pi * k / count):.17g}" for k in range(count)),
            tuple(f"{math.sin(2 * math.pi * k / count):.17g}" for k in range(count)))


# The general 6R's fast pass in C (general_6r.c.j2): det M(psi_3), a trigonometric polynomial of
# degree 8, from its values at 17 points of the circle, its real zeros looked for on a grid of 64.
GENERAL_6R_CIRCLE = {"samples": 17, "grid": 64}
GENERAL_6R_CIRCLE.update(zip(("sample_cos", "sample_sin"), _circle(17)))
GENERAL_6R_CIRCLE.update(zip(("grid_cos", "grid_sin"), _circle(64)))


def seeded_ik(model) -> bool:
    """Whether the package's ik is the numeric solver from fixed seeds: a robot chain with no closed
    form (a kernel set, or a robot built in Python without a chain, has no ik at all)."""
    return isinstance(model, RobotModel) and model.chain is not None and not model.ik and not general_6r(model)


def general_6r(model) -> dict | None:
    """The layout of a general 6R's ik (derivations.ik.general_6r: loop order, signs, shifts and
    offsets), or None where the arm is not one."""
    if not isinstance(model, RobotModel):
        return None
    found = equations_function(model)
    return found[1] if found else None


def ik_method(model) -> str:
    """How the package's ik solves (its IK_METHOD): the family of the closed form, the paper's own
    closed form, or numeric."""
    if not isinstance(model, RobotModel):
        return ""
    if model.ik and model.ik_plan:
        return model.ik_plan[0].removeprefix("family: ")
    if model.ik:
        return "closed form (the paper's)"
    if general_6r(model):
        return "general 6R"
    return "numeric" if model.chain is not None else ""


class _Stages:
    """Names each step for budget messages and reports it, with its time, through ``say``."""

    def __init__(self, name: str, say):
        self.name, self.say = name, say

    @contextlib.contextmanager
    def __call__(self, text: str):
        start = time.perf_counter()
        with budget_stage(f"working on the {text} ({self.name})"):
            yield
        if self.say is not None:
            self.say(f"{self.name}: {text}: {time.perf_counter() - start:.1f} s")


def render_robot(model: RobotModel, description: Path | None = None, backends=("numpy", "c"),
                 verbose: bool = False, latex: bool = True, say=None,
                 in_repository: bool = False, templates: TemplatesAhead | None = None,
                 beside: RatesAndMotion | None = None) -> dict[str, str]:
    """{file name: text} of one robot's package (kernels, its packaging and README, and ``<name>.tex``
    unless ``latex`` is off).

    ``say`` (a callable taking a message) receives each stage with its time.  ``in_repository``:
    the package is one of the repository's ``generated/`` (render_tree), built by `make build`;
    a user's package (``kinegen generate``) tells of its own build script and `pip install` instead.
    ``templates``: the templates being compiled meanwhile (taken before any process is forked here);
    ``beside``: the rates and the dynamics being derived meanwhile (:class:`RatesAndMotion`).
    """
    if templates is not None:
        templates.adopt()
    stage = _Stages(model.name, say)
    origin = describe_origin(model, description)
    # With processes to spare: the equations of motion are derived in one, and the kernels that
    # need neither rates nor dynamics are prepared in another, while this process derives the
    # rates; the LaTeX is written in a third while the rest are prepared (the text is the same
    # either way).
    # (Only where the kernels are RobotModel's own: a subclass's functions() may add or replace some.)
    side = (isinstance(model, RobotModel) and type(model).functions is RobotModel.functions
            and _prepare_jobs(len(model.joint_types) + 4) > 1)
    early = latex_text = motion = None
    try:
        functions = None
        if (side and getattr(model, "inertials", ()) and "_dynamics" not in model.__dict__
                and not (beside is not None and beside.pending)):
            motion = Forked(lambda: (model.dynamics, model.notes.get("dynamics")))
        if side:
            positions = model.position_functions()
            # (the kinematics kernels, which need no ik, are being prepared beside it with the rates)
            taken = kinematics_kernel_names(model) if beside is not None and beside.pending else set()
            mine = [f for f in positions if f.name not in taken]
            if mine:
                early = EarlyKernels(mine, tuple(str(s) for s in model.params))
        if not isinstance(model, KernelSet):
            with stage("rate kinematics"):
                if beside is not None:
                    if beside.pending and latex:  # the LaTeX's det J, in the time this process would wait
                        jacobian_determinant(model)
                    beside.adopt(model)
                model.rates  # derived on first use (and cached on disk)
            if getattr(model, "inertials", ()):  # an arm with inertial parameters: its equations of motion
                with stage("equations of motion"):
                    if motion is not None:
                        job, motion = motion, None
                        _adopt_dynamics(model, *job.result())
                    model.dynamics
                if model.dynamics is None and say is not None:
                    say(f"{model.name}: {model.notes.get('dynamics', 'no dynamics kernels')}")
        if side:  # = model.functions() (assembly.robot_kernels), without building the first ones again
            functions = positions + model.rate_functions() + model.dynamics_functions()
            if latex:
                latex_text = Forked(lambda: latex_backend.render(model, origin))
        with stage("common subexpressions of every kernel"):
            context = robot_context(model, origin, verbose, functions=functions, early=early,
                                    ready=beside.prepared if beside is not None else None)
        early = None  # taken
        context = dict(context, in_repository=in_repository, backends=tuple(backends))
        init = "kernel_set_init.py.j2" if isinstance(model, KernelSet) else "package_init.py.j2"
        files = {
            "__init__.py": TEMPLATES.get_template(init).render(context),
            "_runtime.py": TEMPLATES.get_template("runtime.py.j2").render(context),
        }
        if context["general_6r"]:  # the numpy backend's eigen-solve and Newton polish of a general 6R's ik (C: general_6r.c.j2)
            files["_general_6r.py"] = TEMPLATES.get_template("general_6r.py.j2").render(context)
        for backend in backends:
            with stage(f"{backend} kernels"):
                files.update(BACKENDS[backend].render(context))
        for template, filename in PACKAGING:
            files[filename] = TEMPLATES.get_template(template).render(context)
        if latex and not isinstance(model, KernelSet):  # the LaTeX fragment describes a robot
            with stage("LaTeX"):
                job, latex_text = latex_text, None
                files.update(job.result() if job is not None else latex_backend.render(model, origin))
    except BaseException:
        if beside is not None:
            beside.cancel()
        for job in (early, latex_text, motion):
            if job is not None:
                job.cancel()
        raise
    return files


class RatesAndMotion(_SideJob):
    """A model's rate kinematics and equations of motion derived in a forked process while this one
    derives its inverse kinematics: ``derivations.load(..., before_ik=this)`` starts it once the
    model's frames and Jacobians exist (a description's model derived afresh; none for one from
    the cache), :func:`render_robot` takes its results when it reaches the rates.  The ik of a
    7-joint arm that holds a joint free takes seconds (Romeo's left arm: 7.5 s, 1.7 s since its
    branches are substituted when read), and the rates and the dynamics need nothing of it: the
    process also prepares their kernels (CSE, staging, printing ahead), in worker processes of its
    own.  (Only where the kernels are RobotModel's own.)"""

    def __init__(self):
        self.prepared: dict = {}  # {kernel name: prepared_functions' result}, once adopted

    def __call__(self, model: RobotModel) -> None:
        if (self._job is None and model.chain is not None and type(model).functions is RobotModel.functions
                and _prepare_jobs(4) > 1):
            self._job = Forked(lambda: _rates_and_motion(model), group=True)

    def adopt(self, model: RobotModel) -> None:
        """Give ``model`` what the forked process derived (waiting for it), and keep the kernels it
        prepared (``prepared``); nothing if none was started."""
        taken = self._take()
        if taken is not None:
            rates, dynamics, note, self.prepared = taken
            model.__dict__["_rate_kinematics"] = rates
            if getattr(model, "inertials", ()):
                _adopt_dynamics(model, dynamics, note)


def _rates_and_motion(model: RobotModel) -> tuple:
    """(rates, dynamics, its note, {kernel name: prepared}) of ``model``: in the process
    :class:`RatesAndMotion` forks, which prepares the kernels that need no ik (the kinematics', the
    rates' and the dynamics'), with worker processes of its own, while its parent derives the ik."""
    rates, dynamics = model.rates, model.dynamics
    functions = kinematics_kernels(model) + model.rate_functions() + model.dynamics_functions()
    prepared = _prepared_by_name(functions, tuple(str(s) for s in model.params))
    return rates, dynamics, model.notes.get("dynamics"), prepared


def kinematics_kernel_names(model: RobotModel) -> set[str]:
    """The names of ``model``'s kinematics kernels (fk, frames, the Jacobians, task): the first of its
    position functions, which need no ik."""
    return {f.name for f in kinematics_kernels(model)}


def _adopt_dynamics(model: RobotModel, dynamics, note: str | None) -> None:
    """``model``'s equations of motion as a forked process derived them (``model.dynamics`` there),
    with its note (why there are none, or no forward dynamics); a budget that cut them short there
    counts here too (:func:`derivations.support.budget.degraded`)."""
    model.__dict__["_dynamics"] = dynamics
    if note is not None:
        model.notes["dynamics"] = note
        if dynamics is None:
            degraded(note)


def _render_named(name: str, verbose: bool) -> dict[str, str]:
    """{file name: text} of the registered robot or kernel set ``name`` (a worker of render_tree)."""
    if name in derivations.KERNEL_SETS:
        model, source = derivations.load_kernel_set(name), derivations.KERNEL_SETS[name]
    else:
        model, source = derivations.load(name, verbose=verbose), derivations.ROBOTS[name]
    return render_robot(model, source, verbose=verbose, in_repository=True)


class NotFiniteError(ValueError):
    """A description whose kernels, run in double precision at its defaults, give inf or NaN."""


def check_finite(model: RobotModel, folder: Path) -> None:
    """Run the numpy kernels just written in ``folder`` (fk and the Jacobian, at q = 0 and three
    configurations within the limits, at the parameters' defaults) and refuse the package when an
    entry is not finite: each field of a description is checked finite on its own, but what the
    kernels compute in doubles can still overflow (``sqrt(p**2 + 1) - p`` with p = 1e200, exactly
    1e-200 and 0.5 apart, is inf - inf)."""
    import importlib.util
    import warnings
    module_name = f"_kinegen_check_{model.name}_{os.getpid()}"
    spec = importlib.util.spec_from_file_location(module_name, folder / "__init__.py",
                                                  submodule_search_locations=[str(folder)])
    package = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = package
    try:
        spec.loader.exec_module(package)
        rng = np.random.default_rng(0)
        low = np.array([lim[0] if lim else -np.pi for lim in model.limits])
        high = np.array([lim[1] if lim else np.pi for lim in model.limits])
        q = np.vstack([np.zeros(model.n), rng.uniform(low, high, (3, model.n))])
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            for kernel in ("fk", "jacobian"):
                values = getattr(package, kernel)(q)
                if not np.isfinite(values).all():
                    bad = values[~np.isfinite(values)].flat[0]
                    raise NotFiniteError(f"{model.name}: {kernel} is {bad} at the parameters' defaults when computed "
                                         "in double precision (a number of the description overflows a double "
                                         "on the way); nothing was written")
    finally:
        # (a snapshot: the C build imports in a thread of its own meanwhile, see _fill)
        for name in [n for n in list(sys.modules) if n == module_name or n.startswith(module_name + ".")]:
            del sys.modules[name]


class SettingError(ValueError):
    """An environment setting of kinegen (``KINEGEN_JOBS``) that cannot be used."""


def _joint_count(name: str) -> int:
    """Joints of a registered robot's TOML description (0 for other registrations)."""
    path = derivations.ROBOTS.get(name)
    if path is None or path.suffix != ".toml":
        return 0
    return len(read_description(path).joints)


OPT_LEVELS = ("-O0", "-O1", "-O2", "-O3", "-Os")  # as each package's build_c.py takes them


def check_opt_level() -> None:
    """``$KINEGEN_OPT``, the portable build's optimisation level (build_c.py reads it), checked
    before any work: one of OPT_LEVELS, or unset."""
    level = os.environ.get("KINEGEN_OPT")
    if level and level not in OPT_LEVELS:
        raise SettingError(f"KINEGEN_OPT must be one of {', '.join(OPT_LEVELS)} (or unset: -O2), "
                           f"got {terminal_text(level, 40)}")


def default_jobs() -> int:
    """Worker processes for render_tree: ``$KINEGEN_JOBS``, else the CPUs this process may use."""
    env = os.environ.get("KINEGEN_JOBS")
    if env:
        try:
            jobs = int(env)
        except ValueError:
            raise SettingError(f"KINEGEN_JOBS must be a positive integer, got {env!r}") from None
        if jobs < 1:
            raise SettingError(f"KINEGEN_JOBS must be a positive integer, got {env!r}")
        return jobs
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def render_tree(names=None, verbose: bool = False, jobs: int | None = None) -> dict[str, str]:
    """The whole ``generated/`` tree as {relative path: text}: every robot, then every kernel set.

    Robots are derived and rendered in ``jobs`` processes (default :func:`default_jobs`):
    each is independent and its text does not depend on the process (tested), so the
    tree is the same in any number of them.  A cold Puma 560 alone takes about half
    of the whole; on two cores the rest runs beside it.
    """
    names = list(derivations.ROBOTS) + list(derivations.KERNEL_SETS) if names is None else list(names)
    robots = [n for n in names if n not in derivations.KERNEL_SETS]
    tree = {"__init__.py": TEMPLATES.get_template("generated_init.py.j2").render(
        robots=robots, kernel_sets=[n for n in names if n in derivations.KERNEL_SETS])}
    jobs = min(default_jobs() if jobs is None else jobs, len(names))
    if jobs > 1:
        with concurrent.futures.ProcessPoolExecutor(max_workers=jobs) as pool:
            # The most joints first: symbolic work grows steeply with them (the Puma's
            # wrist partition), so the slowest starts at once and the rest fill in beside it.
            futures = {name: pool.submit(_render_named, name, verbose)
                       for name in sorted(names, key=lambda n: -_joint_count(n))}
            rendered = [futures[name].result() for name in names]
    else:
        rendered = [_render_named(name, verbose) for name in names]
    for name, files in zip(names, rendered):
        for filename, text in files.items():
            tree[f"{name}/{filename}"] = text
    return tree


class OutputExistsError(ValueError):
    """The output folder of a standalone package exists and --force was not given."""


def check_package_folder(out: Path) -> None:
    """``out``'s name must be importable as a package of its own: an identifier that is no Python
    keyword and no standard-library module (a package named json would shadow the real one)."""
    import keyword
    name = Path(out).name
    if not name.isidentifier() or keyword.iskeyword(name):
        raise OutputExistsError(f"{out}: the package folder name must be a Python identifier (not a keyword) "
                                "to be importable")
    if name in sys.stdlib_module_names:
        raise OutputExistsError(f"{out}: {name!r} is a module of Python's standard library; a package of that "
                                "name would shadow it (choose another --out)")


def claim_output(out: Path, force: bool = False) -> bool:
    """Take the package folder ``out`` for this run before any work is done.

    Without ``force`` the folder is created, empty, by this run (an atomic ``mkdir``: anything
    already there, a dangling symbolic link included, is refused); returns True.  With
    ``force`` an existing package folder is accepted, to be replaced when the new one is
    complete (False); where there is none, it is created as without ``force`` (True).
    """
    out = Path(out)
    check_package_folder(out)
    if out.is_symlink() and not out.exists():
        raise OutputExistsError(f"{out}: a symbolic link to nothing; remove it or choose another --out")
    existing = next(p for p in out.absolute().parents if p.exists())
    if not existing.is_dir():
        raise OutputExistsError(f"{existing}: not a folder, so {out} cannot be made inside it")
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        out.mkdir()
        return True
    except FileExistsError:
        if not force:
            raise OutputExistsError(f"{out}: output folder exists (use --force to replace it)") from None
        if not out.is_dir():
            raise OutputExistsError(f"{out}: exists and is not a folder (--force replaces only a package folder)") from None
        return False


def _scratch_prefix(out: Path) -> str:
    """The name every scratch folder of a run writing ``out`` starts with: it holds the run's process
    id, so that a later run can tell a killed run's leftovers from a running one's."""
    return f".{out.name}-kinegen-{os.getpid()}-"


def clear_leftovers(out: Path, say=lambda message: None) -> list[Path]:
    """Remove the scratch folders beside ``out`` that runs killed before they could clean up left
    (``kill -9``: their process is gone); returns them, and says so."""
    removed = []
    pattern = re.compile(rf"^\.{re.escape(out.name)}-kinegen-(\d+)-")
    for path in sorted(Path(out).parent.glob(f".{out.name}-kinegen-*")):
        match = pattern.match(path.name)
        if not match or not path.is_dir() or path.is_symlink():
            continue
        try:
            os.kill(int(match[1]), 0)
            continue  # the run that made it is still running
        except ProcessLookupError:
            pass
        except (PermissionError, OverflowError):
            continue
        shutil.rmtree(path, ignore_errors=True)
        removed.append(path)
        say(f"removed {terminal_text(path)}: a scratch folder left by a run that was killed")
    return removed


def release_output(out: Path) -> None:
    """Give back a folder :func:`claim_output` created, if it is still empty (a run that failed)."""
    with contextlib.suppress(OSError):
        Path(out).rmdir()


def write_package(model: RobotModel, description: Path | None, out: Path, backends=("numpy", "c"),
                  force: bool = False, build=None, say=lambda message: None, files=None,
                  claimed: bool = False) -> Path:
    """Write a self-contained package for ``model`` into the folder ``out``.

    The package holds the numpy kernels, the C header and source with their
    cffi build script, and the input checks; ``build(folder)`` (when given)
    compiles the C extension.  Everything is written and built in a scratch
    folder beside ``out`` and moved into place at the end, so a failure leaves
    no partial package behind.  ``claimed``: ``out`` is the empty folder this run created
    (:func:`claim_output`); the package replaces it only while it is still empty, and files that
    appeared in it meanwhile are left as they are.
    """
    out = Path(out)
    if claimed:
        return _replace_claimed(model, description, out, backends, build, say, files)
    if out.exists() and not force:
        raise OutputExistsError(f"{out}: output folder exists (use --force to replace it)")
    if out.exists() and not out.is_dir():
        raise OutputExistsError(f"{out}: exists and is not a folder (--force replaces only a package folder)")
    if not out.name.isidentifier():
        raise ValueError(f"{out}: the package folder name must be a Python identifier to be importable")
    backends = tuple(dict.fromkeys(("numpy", *backends)))  # the C binding reads the numpy module's constants
    if files is None:  # (already rendered: files)
        say(f"{model.name}: rendering {', '.join(backends)} kernels")
        files = render_robot(model, description, backends=backends, say=say)
    out.parent.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=_scratch_prefix(out), dir=out.parent))
    try:
        _fill(model, scratch, files, build if "c" in backends else None, say)
        aside = None
        if out.exists():  # (--force) moved aside, and removed only once the new package is in place
            aside = Path(tempfile.mkdtemp(prefix=_scratch_prefix(out) + "old-", dir=out.parent))
            os.replace(out, aside / out.name)
        os.replace(scratch, out)
        if aside is not None:
            shutil.rmtree(aside, ignore_errors=True)
    except BaseException:
        shutil.rmtree(scratch, ignore_errors=True)
        raise
    return out


def _replace_claimed(model, description, out: Path, backends, build, say, files) -> Path:
    backends = tuple(dict.fromkeys(("numpy", *backends)))
    if files is None:
        files = render_robot(model, description, backends=backends, say=say)
    scratch = Path(tempfile.mkdtemp(prefix=_scratch_prefix(out), dir=out.parent))
    try:
        _fill(model, scratch, files, build if "c" in backends else None, say)
        try:
            os.replace(scratch, out)  # onto the empty folder this run made: atomic, and refused if not empty
        except OSError as exc:
            if exc.errno in (errno.ENOTEMPTY, errno.EEXIST):
                raise OutputExistsError(f"{out}: files appeared in the output folder while this run worked; "
                                        "they are left as they are and nothing was written") from None
            raise
    except BaseException:
        shutil.rmtree(scratch, ignore_errors=True)
        raise
    return out


def _fill(model, scratch: Path, files: dict[str, str], build, say) -> None:
    """Write ``files`` into the package folder ``scratch``, check the numpy kernels' values
    (:func:`check_finite`) and run ``build(scratch)`` (when given) beside that check, in a
    thread of its own: the build waits on its compilers (a KR 210's: 3 s on two cores) while the
    check imports the numpy kernels (0.4 s), and the folder is left to the caller only once the
    build has ended, whatever happened meanwhile (nothing is being written into it any more)."""
    for filename, text in files.items():
        (scratch / filename).write_text(text, encoding="utf-8")
    building = None
    if build is not None:
        say(f"{model.name}: compiling the C kernels and their cffi extension")
        building = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="kinegen-build")
        built = building.submit(build, scratch)
    try:
        if isinstance(model, RobotModel) and model.chain is not None:
            check_finite(model, scratch)
        if building is not None:
            built.result()
    finally:
        if building is not None:
            building.shutdown(wait=True)
    os.chmod(scratch, 0o777 & ~_umask())  # mkdtemp makes it 0700; a package folder follows the umask


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file of a unique name beside it, moved into
    place: a reader sees the old file or the new one, and two writers never share a scratch name."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".part")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_tree(tree: dict[str, str], root: Path = GENERATED, robots=None) -> list[str]:
    """Write ``tree`` under ``root``; return the paths that changed.

    Generated files of the listed robots that the tree no longer holds are
    removed, so a renamed kernel leaves nothing stale behind.
    """
    changed = []
    for rel, text in sorted(tree.items()):
        path = root / rel
        if path.is_file() and path.read_text(encoding="utf-8") == text:
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, text)
        changed.append(rel)
    for robot in robots or {rel.split("/")[0] for rel in tree if "/" in rel}:
        folder = root / robot
        for path in sorted(folder.glob("*")):
            rel = f"{robot}/{path.name}"
            if path.suffix in OWNED_SUFFIXES and rel not in tree:
                path.unlink()
                changed.append(f"{rel} (removed)")
    return changed


def stale_files(tree: dict[str, str], root: Path = GENERATED) -> list[str]:
    """Paths under ``root`` that differ from ``tree`` (missing, changed or left over)."""
    stale = []
    for rel, text in sorted(tree.items()):
        path = root / rel
        if not path.is_file():
            stale.append(f"{rel} (missing)")
        elif path.read_text(encoding="utf-8") != text:
            stale.append(f"{rel} (out of date)")
    robots = {rel.split("/")[0] for rel in tree if "/" in rel}
    for robot in sorted(robots):
        for path in sorted((root / robot).glob("*")):
            rel = f"{robot}/{path.name}"
            if path.suffix in OWNED_SUFFIXES and rel not in tree:
                stale.append(f"{rel} (not generated any more)")
    # What an interrupted write or a killed run can leave: temporary files and scratch folders (a
    # package's build folders included).
    for path in sorted(root.rglob("*")):
        if path.name.endswith(".part") or (path.is_dir() and path.name.startswith(".") and path.parent == root) \
                or (path.is_dir() and path.name.startswith(".kinegen-build-")):
            stale.append(f"{path.relative_to(root).as_posix()} (stray: left by an interrupted run)")
    return stale
