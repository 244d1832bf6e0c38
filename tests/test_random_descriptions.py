"""Random valid descriptions (issue #17, fuzzing): each generated, compiled strictly and verified.

A hypothesis strategy writes description files of everything the format allows: 1 to 7
joints, revolute and prismatic mixed, standard and modified (Craig) DH, offsets and limits
(some in ``deg()``), a ``[tool]`` and a ``[base]`` frame, a ``[params]`` table whose names
the fields use in expressions (``-l1``, ``l2/2 + 0.05``, ``sqrt(l1**2 + 0.01)``,
``l1*cos(deg(30))``, ...), and every task the chain allows (``phi`` where every revolute axis
is parallel to the base z axis).  Each file then goes the user's way:

1. ``kinegen generate FILE --out DIR`` (codegen.cli.main, in this process, in a scratch folder
   and an isolated KINEGEN_CACHE; the short profile calls what it runs, without the LaTeX) with
   KINEGEN_PORTABLE=1: the C is compiled as ``make build`` compiles it, the layout the extension
   uses once under ``-std=c99 -Wall -Wextra -Werror -pedantic`` (plain C99, the cheapest full
   compile) and the other layouts through the same flags' front end (``-fsyntax-only``), then
   linked into the cffi extension.  The command's documented refusal of a description past its
   --time-limit (120 s) or --memory-limit (some random arms of six or seven joints) is counted,
   not failed;
2. every kernel of both backends against SymPy at 30 digits (codegen.verify.verify_model,
   what ``kinegen verify`` runs, with fewer points; a run-time solve to 1e-12 past what the
   rounding of its float64 system can move it, codegen.verify.solve_reference);
3. fk and jacobian of both backends against tests/test_zoo.py's DH product of the file as
   ``tomllib`` reads it (the test's own evaluator and matrices, not the project's parser);
4. where the arm got an ik: FK(IK(x)) = x by that same DH product, for x from it; and the rate
   maps give back the task rates they are given (where regular).

The short profile (``make test``) tries three files of up to three joints; HYPOTHESIS_PROFILE=fuzz
(``make fuzz``) 100 of up to four joints and 100 of five to seven, side by side under xdist.
``KINEGEN_FUZZ_REPORT=FILE`` appends a line per description: what it holds, seconds, outcome.
"""
from __future__ import annotations

import contextlib
import importlib
import io
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, note, settings
from hypothesis import strategies as st

import derivations
from codegen import build, cli, generate
from codegen.verify import verify_model
from test_zoo import fk as dh_fk
from test_zoo import ik_target, jacobian as dh_jacobian, read_arm, relative_error, task_rows, wrap

pytestmark = pytest.mark.fuzz

LONG = settings.default.max_examples >= 100      # the fuzz profile
# Joint counts per test item: the short profile tries small arms only; the long one adds a lane of
# large ones, which pytest-xdist runs beside the first (examples: a tenth of the profile's, per lane).
LANES = [(1, 4), (5, 7)] if LONG else [(1, 3)]
EXAMPLES = max(2, settings.default.max_examples // 20 if LONG else 2)
TOLERANCE = 1e-12
ROUND_TRIP = 1e-9

PARAM_NAMES = ("l1", "l2", "h", "reach", "lw", "off_z")
ANGLES = ("0", "pi/2", "-pi/2", "pi", "pi/3", "-pi/4", "deg(30)", "deg(-120)", "0.3")
PLANAR_TWISTS = ("0", "pi", "-pi")
NUMBERS = ("0", "0.1", "0.25", "-0.05", "0.4318", "1/3")


def lengths(names):
    """A length field: a number, or an expression of the parameters (when there are some)."""
    plain = st.sampled_from(NUMBERS)
    if not names:
        return plain
    name = st.sampled_from(names)
    forms = st.sampled_from(["{a}", "-{a}", "{a}/2 + 0.05", "2*{a} - {b}", "sqrt({a}**2 + 0.01)",
                             "{a}*cos(deg(30))", "({a} + {b})/3"])
    expression = st.builds(lambda f, a, b: f.format(a=a, b=b), forms, name, name)
    return st.one_of(plain, expression, expression)


def toml_value(text):
    """A field in TOML: numbers bare (some of them), expressions quoted."""
    try:
        return repr(float(text)) if "/" not in text else f'"{text}"'
    except ValueError:
        return f'"{text}"'


@st.composite
def descriptions(draw, min_joints=1, max_joints=7):
    """(TOML text without its name, what it says) of a valid description."""
    n = draw(st.integers(min_joints, max_joints), label="joints")
    convention = draw(st.sampled_from(["standard", "modified"]), label="convention")
    names = draw(st.lists(st.sampled_from(PARAM_NAMES), unique=True, max_size=4), label="params")
    planar = draw(st.booleans(), label="planar")
    lines = [f'convention = "{convention}"']
    params = ["[params]"]
    for p in names:
        value = draw(st.one_of(st.sampled_from(["0.3", "0.125", "0.45", "0.0825"]),
                               st.sampled_from(['"deg(10)"', '"sqrt(2)/10"', '"0.1*3"', '"1/7"'])))
        params.append(f"{p} = {value}")
    length = lengths(list(names))
    twist = st.sampled_from(PLANAR_TWISTS) if planar else st.sampled_from(ANGLES)
    joints, types = [], []
    for _ in range(n):
        kind = draw(st.sampled_from("RRP"), label="type")
        types.append(kind)
        fields = {"type": f'"{kind}"', "a": toml_value(draw(length)), "alpha": toml_value(draw(twist))}
        if kind == "R":
            fields["d"] = toml_value(draw(length))
            if draw(st.booleans()):
                fields["offset"] = toml_value(draw(st.sampled_from(ANGLES)))
            if draw(st.booleans()):
                fields["limits"] = draw(st.sampled_from(['["deg(-170)", "deg(170)"]', "[-2.5, 2.9]",
                                                         '["-pi", "pi/2"]', '["deg(-45)", "deg(225)"]']))
        else:
            fields["theta"] = toml_value(draw(twist if planar else st.sampled_from(ANGLES)))
            if draw(st.booleans()):
                fields["offset"] = toml_value(draw(st.sampled_from(["0.1", "-0.05", "0"])))
            if draw(st.booleans()):
                fields["limits"] = draw(st.sampled_from(["[0, 0.4]", "[-0.2, 0.3]", '["-1/4", "1/4"]']))
        joints.append("[[joint]]\n" + "\n".join(f"{k} = {v}" for k, v in fields.items()))
    frames = []
    for frame in ("tool", "base"):
        if draw(st.booleans(), label=frame):
            xyz = [toml_value(draw(length)) for _ in range(3)]
            rpy = (["0", "0", draw(st.sampled_from(ANGLES))] if planar
                   else [draw(st.sampled_from(ANGLES)) for _ in range(3)])
            frames.append(f"[{frame}]\nxyz = [{', '.join(xyz)}]\nrpy = [{', '.join(toml_value(v) for v in rpy)}]")
    tasks = [["pose"], ["x", "y", "z"], ["x", "y"], ["z"], ["x", "z"]]
    if planar:
        tasks += [["x", "y", "phi"], ["phi"], ["x", "y", "z", "phi"]]
    task = draw(st.sampled_from(tasks), label="task")
    lines.append("task = [" + ", ".join(f'"{t}"' for t in task) + "]")
    text = "\n".join(lines + params + joints + frames) + "\n"
    return text, dict(joints=n, types="".join(types), convention=convention, planar=planar, task=task,
                      params=len(names), tool=any(f.startswith("[tool]") for f in frames),
                      base=any(f.startswith("[base]") for f in frames))


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    """A scratch folder and the environment for the whole module: an isolated derivation cache,
    portable C (plain C99 -O3 under the strict flags, a fraction of the vectorised build's time)."""
    root = tmp_path_factory.mktemp("random_descriptions")
    saved = {k: os.environ.get(k) for k in ("KINEGEN_CACHE", "KINEGEN_PORTABLE")}
    os.environ.update(KINEGEN_CACHE=str(root / "cache"), KINEGEN_PORTABLE="1")
    yield root
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


def _report(record):
    path = os.environ.get("KINEGEN_FUZZ_REPORT")
    if path:
        with open(path, "a") as handle:
            handle.write(json.dumps(record) + "\n")


@pytest.mark.parametrize("lane", LANES, ids=[f"joints{a}-{b}" for a, b in LANES])
@settings(max_examples=EXAMPLES, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(data=st.data())
def test_a_random_description_generates_compiles_and_verifies(workspace, lane, data):
    text, info = data.draw(descriptions(*lane), label="description")
    note(text)
    event(f"{info['joints']} joints")
    generate_and_check(workspace, text, info)


_SEEN = [0]


def generate_and_check(workspace: Path, text: str, info: dict):
    """Steps 1 to 4 of the module docstring for one description (``text`` without its name); a
    line in the KINEGEN_FUZZ_REPORT file with the outcome: "generate failed" (derivation,
    rendering or the strict compile), "over its budget" (the command's documented refusal),
    "verify failed" (any check after), "verified"."""
    _SEEN[0] += 1
    name = f"rand{os.getpid()}_{_SEEN[0]}"
    folder = workspace / name
    folder.mkdir()
    path = folder / f"{name}.toml"
    path.write_text(f'name = "{name}"\n' + text)
    record = dict(info, name=name, text=text, outcome="generate failed")
    start = time.perf_counter()
    try:
        if not generate_package(path, folder / name):
            record["outcome"] = "over its budget"
            return
        record["outcome"] = "verify failed"  # generated, and its C compiled strictly
        sys.path.insert(0, str(folder))
        importlib.invalidate_caches()
        try:
            package = importlib.import_module(name)
        finally:
            sys.path.remove(str(folder))
        modules = {"numpy": package.load("numpy"), "c": package.load("c")}
        model = derivations.load(path)
        checks = verify_model(model, modules, samples=3, seed=len(text))
        arm = read_arm(path)
        failed = [c for c in checks if not c.ok]
        assert not failed, f"{failed}\n{text}"
        if singular_everywhere(arm):
            check_a_degenerate_arm(arm, modules)
        check_against_the_dh_product(path, model, modules)
        check_rate_round_trips(arm, modules)
        record["outcome"] = "verified"
    except BaseException as exc:
        record["error"] = " ".join(str(exc).split())[:500]
        raise
    finally:
        record["seconds"] = round(time.perf_counter() - start, 2)
        _report(record)


def generate_package(path: Path, out: Path):
    """``kinegen generate FILE --out DIR`` (the long profile), or what it runs without the LaTeX
    (the short one: the LaTeX took 10 s of a 3R arm's 14 s, with sqrt() in its lengths).  False
    where the command refused the description for its time or memory budget, as documented."""
    if LONG:
        errors = io.StringIO()
        with contextlib.redirect_stderr(errors):
            status = cli.main(["--quiet", "generate", str(path), "--out", str(out)])
        if status == 2 and ("time budget of" in errors.getvalue() or "memory cap of" in errors.getvalue()):
            # The documented refusal of a description slower than --time-limit (default 120 s) or
            # larger than --memory-limit: some random arms of six and seven joints with general
            # twists and rotated frames.
            assert "; nothing was written (--" in errors.getvalue() and not out.exists()
            event("over its budget")
            return False
        assert status == 0, f"kinegen generate exited {status}: {errors.getvalue()}"
        return True
    model = derivations.load(path)
    files = generate.render_robot(model, path, latex=False)
    generate.write_package(model, path, out, files=files, build=lambda folder: build.build_package(folder, model.name))
    return True


# An arm singular everywhere (two axes in line, a planar arm asked for a pose): its damped
# solutions keep the part of rounding-level singular values, which differs between the two
# backends' SVDs (Jacobi rotations, LAPACK) by up to cond_limit^2 eps; check_a_degenerate_arm
# holds them to that, by this file's Jacobian.
DAMPED_RTOL = 1e4 ** 2 * np.finfo(float).eps


def configurations(arm, count=20, seed=None):
    rng = np.random.default_rng(len(arm.types) if seed is None else seed)
    lows, highs = zip(*[lim if lim is not None else ((-math.pi, math.pi) if kind == "R" else (-0.5, 0.5))
                        for kind, lim in zip(arm.types, arm.limits)])
    return rng.uniform(lows, highs, (count, arm.n))


def singular_everywhere(arm) -> bool:
    """The rows of the task (test_zoo.task_rows of this file's Jacobian) lose rank at every one of
    20 random configurations."""
    singular_values = np.linalg.svd(task_rows(arm, dh_jacobian(arm, configurations(arm))), compute_uv=False)
    return bool((singular_values[:, -1] <= 1e-9 * np.maximum(singular_values[:, 0], 1e-300)).all())


def check_a_degenerate_arm(arm, modules):
    """Manipulability 0 to rounding (by this file's Jacobian), flagged singular, and the damped
    solutions of the two backends within DAMPED_RTOL of each other."""
    event("singular everywhere")
    q = configurations(arm, 10, seed=5)
    A = task_rows(arm, dh_jacobian(arm, q))
    scale = max(1.0, np.abs(A).max()) ** min(A.shape[-2:])
    xd = np.random.default_rng(6).uniform(-1, 1, (len(q), len(modules["numpy"].TASK)))
    solved = {}
    for backend, module in modules.items():
        w, singular = module.manipulability(q)
        assert singular.all() and np.abs(w).max() <= 1e-12 * scale, (backend, w)
        solved[backend], singular = module.joint_velocity(q, xd)
        assert singular.all()
    size = np.maximum(np.abs(solved["numpy"]).max(axis=-1), np.abs(xd).max(axis=-1) / max(np.abs(A).max(), 1e-300))
    assert (np.abs(solved["numpy"] - solved["c"]).max(axis=-1) <= DAMPED_RTOL * size).all()


def check_rate_round_trips(arm, modules):
    """Where the task rows are regular (no singular flag): the joint rates the rate maps give take
    the arm to the task rates asked for: task_velocity(q, joint_velocity(q, xd)) = xd for xd =
    task_velocity(q, qd), and the same of the accelerations (redundant arms included: any joint
    rates that reach xd do)."""
    q = configurations(arm, 10, seed=7)
    rng = np.random.default_rng(8)
    qd, qdd = rng.uniform(-1, 1, q.shape), rng.uniform(-1, 1, q.shape)
    for backend, module in modules.items():
        xd = module.task_velocity(q, qd)
        back, singular = module.joint_velocity(q, xd)
        miss = np.abs(module.task_velocity(q, back) - xd).max(axis=-1) / np.maximum(1.0, np.abs(xd).max(axis=-1))
        assert (miss[~singular] <= 1e-9).all(), (backend, "joint_velocity", miss.max())
        xdd = module.task_acceleration(q, qd, qdd)
        back, singular = module.joint_acceleration(q, qd, xdd)
        miss = np.abs(module.task_acceleration(q, qd, back) - xdd).max(axis=-1) / np.maximum(1.0, np.abs(xdd).max(axis=-1))
        assert (miss[~singular] <= 1e-9).all(), (backend, "joint_acceleration", miss.max())


def check_against_the_dh_product(path: Path, model, modules):
    """fk and jacobian (both backends) against tests/test_zoo.py's DH product; ik round trip."""
    arm = read_arm(path)
    q = configurations(arm)
    T, J = dh_fk(arm, q), dh_jacobian(arm, q)
    for backend, module in modules.items():
        assert relative_error(module.fk(q), T) < TOLERANCE, backend
        assert relative_error(module.jacobian(q), J) < TOLERANCE, backend
    if not model.ik:
        event(f"no ik: {model.ik_unsupported[:60]}")
        return
    event("has ik")
    if arm.task == ["pose"]:
        x = ik_target(arm, T)
    else:
        coordinates = {"x": T[:, 0, 3], "y": T[:, 1, 3], "z": T[:, 2, 3], "phi": np.arctan2(T[:, 1, 0], T[:, 0, 0])}
        x = np.stack([coordinates[t] for t in arm.task], axis=-1)
    angles = [i for i, t in enumerate(arm.task) if t == "phi"]
    for backend, module in modules.items():
        if getattr(model, "ik_free", None) is not None:
            Q, valid = module.ik(x, free=q[:, model.ik_free])
        else:
            Q, valid = module.ik(x)
        reached = dh_fk(arm, np.where(valid[..., None], Q, 0.0))
        if arm.task == ["pose"]:
            got = ik_target(arm, reached)
        else:
            coordinates = {"x": reached[..., 0, 3], "y": reached[..., 1, 3], "z": reached[..., 2, 3],
                           "phi": np.arctan2(reached[..., 1, 0], reached[..., 0, 0])}
            got = np.stack([coordinates[t] for t in arm.task], axis=-1)
        miss = np.abs(got - x[:, None, :])
        miss[..., angles] = np.abs(wrap(miss[..., angles]))
        miss = np.where(valid, miss.max(axis=-1), 0.0) / np.maximum(1.0, np.abs(x).max(axis=-1))[:, None]
        assert miss.max() <= ROUND_TRIP, (backend, float(miss.max()))
        assert valid.any(axis=-1).all(), f"{backend}: no valid branch for q = {q[~valid.any(axis=-1)]}"


def test_the_strategy_covers_what_the_issue_asks():
    """The strategy can write every feature the issue lists (on its own draws, without deriving any)."""
    seen = {"joints": set(), "types": set(), "convention": set(), "planar": set(), "tool": set(), "base": set(),
            "params": set(), "task": set()}

    @settings(max_examples=300, database=None, derandomize=True)
    @given(description=descriptions())
    def collect(description):
        text, info = description
        seen["joints"].add(info["joints"])
        seen["types"].update(info["types"])
        for key in ("convention", "planar", "tool", "base"):
            seen[key].add(info[key])
        seen["params"].add(info["params"] > 0)
        seen["task"].add(tuple(info["task"]))

    collect()
    assert seen["joints"] == set(range(1, 8)) and seen["types"] == {"R", "P"}
    assert seen["convention"] == {"standard", "modified"} and seen["tool"] == seen["base"] == {True, False}
    assert seen["params"] == {True, False} and seen["planar"] == {True, False}
    assert ("phi",) in seen["task"] and ("pose",) in seen["task"] and len(seen["task"]) >= 6


# --------------------------------------------------------------------------- what the fuzz found

_NUMPY_PACKAGES: dict[str, tuple] = {}


@pytest.fixture(scope="module")
def numpy_package(tmp_path_factory):
    """``kinegen generate`` of a description text (named by its first line), numpy only, imported:
    once per text in this module (the tests below share four packages), from a cold cache."""
    root = tmp_path_factory.mktemp("numpy_packages")

    def make(text):
        if text not in _NUMPY_PACKAGES:
            name = text.split('"')[1]
            path = root / f"{name}.toml"
            path.write_text(text)
            previous = os.environ.get("KINEGEN_CACHE")
            os.environ["KINEGEN_CACHE"] = str(root / "cache")
            try:
                assert cli.main(["--quiet", "generate", str(path), "--out", str(root / name), "--no-build",
                                 "--backend", "numpy"]) == 0
            finally:
                os.environ.pop("KINEGEN_CACHE") if previous is None else os.environ.update(KINEGEN_CACHE=previous)
            sys.path.insert(0, str(root))
            importlib.invalidate_caches()
            try:
                _NUMPY_PACKAGES[text] = (path, importlib.import_module(name).load("numpy"))
            finally:
                sys.path.remove(str(root))
        return _NUMPY_PACKAGES[text]
    return make


TOOL_ACROSS = 'name = "tool_across"\ntask = ["pose"]\n[[joint]]\ntype = "R"\na = 0.5\n' \
              '[[joint]]\ntype = "R"\na = 0.1\n[tool]\nxyz = [0, 0.3, 0]\n'


def test_joint_acceleration_inverts_task_acceleration_with_a_tool_across_the_last_link(numpy_package):
    """A planar 2R arm (a = 0.5, 0.1) with its tool 0.3 m across the last link, task pose: the joint
    accelerations that task_acceleration's rates came from come back (a regular configuration).
    Found by the fuzz (issue #17): derived afresh (not from the cache), sympy.cse took the terms
    of factor_terms' kept products -(a + b)/10 for each other's, and joint_acceleration was off
    by 0.13 rad/s^2 (codegen.kernels.canonical)."""
    _, module = numpy_package(TOOL_ACROSS)
    q, qd, qdd = np.array([0.3, -0.7]), np.array([0.5, 1.0]), np.array([0.2, -0.4])
    back, singular = module.joint_velocity(q, module.task_velocity(q, qd))
    assert not singular and np.abs(back - qd).max() <= 1e-12  # the velocities do come back
    back, singular = module.joint_acceleration(q, qd, module.task_acceleration(q, qd, qdd))
    assert not singular
    assert np.abs(back - qdd).max() <= 1e-12, f"qdd {qdd} comes back as {back}"


AXES_IN_LINE = 'name = "axes_in_line"\nconvention = "modified"\ntask = ["pose"]\n[[joint]]\ntype = "R"\n' \
               'alpha = "pi/3"\n[[joint]]\ntype = "R"\n'


def test_verify_passes_an_arm_whose_two_axes_are_in_line(numpy_package, monkeypatch, capsys):
    """Two revolute joints about one axis (modified DH, no lengths), task pose: a valid description,
    its kernels right to rounding (check_a_degenerate_arm), which `kinegen verify` should pass."""
    path, module = numpy_package(AXES_IN_LINE)
    monkeypatch.setenv("KINEGEN_CACHE", str(path.parent / "cache"))
    w, singular = module.manipulability([0.3, -0.7])
    assert singular and abs(w) <= 1e-15  # rank 1: the manipulability is 0 to rounding
    status = cli.main(["--quiet", "verify", str(path), "--out", str(path.parent / "axes_in_line"),
                       "--backends", "numpy", "--samples", "3"])
    assert status == 0, capsys.readouterr().out[-1500:]


def _off_by(module, kernel: str, by: float):
    """``module`` with ``kernel``'s first output moved by ``by`` (absolute, every entry)."""
    import types
    wrapped = types.SimpleNamespace(**{name: getattr(module, name) for name in dir(module) if not name.startswith("__")})
    original = getattr(module, kernel)

    def moved(*args, **kwargs):
        first, *rest = original(*args, **kwargs)
        return (first + by, *rest)
    setattr(wrapped, kernel, moved)
    return wrapped


@pytest.mark.parametrize("text, kernel, by", [
    (AXES_IN_LINE, "joint_velocity", 1e-7),   # allowed ~1.5e-9 there (rounding-level singular value)
    (AXES_IN_LINE, "manipulability", 1e-12),  # allowed ~7e-15
    (TOOL_ACROSS, "joint_velocity", 1e-10),   # regular: allowed ~1e-13 relative
    (TOOL_ACROSS, "joint_acceleration", 1e-10),
])
def test_verify_still_fails_a_solve_off_by_more_than_its_rounding(numpy_package, monkeypatch, text, kernel, by):
    """What verify allows a run-time solve (solve_reference: the rounding of its float64 system,
    through the solve's conditioning) does not let a wrong answer through: the same kernels,
    moved a little past it, fail; unmoved, they pass."""
    path, module = numpy_package(text)
    monkeypatch.setenv("KINEGEN_CACHE", str(path.parent / "cache"))
    model = derivations.load(path)

    def check(modules):
        return next(c for c in verify_model(model, modules, samples=3) if c.kernel == kernel)
    assert check({"numpy": module}).ok
    moved = check({"numpy": _off_by(module, kernel, by)})
    assert not moved.ok, moved
