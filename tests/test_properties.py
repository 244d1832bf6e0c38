"""Hypothesis properties of every registered package, in both backends (issue #17: fuzzing).

Every kernel of every package in ``derivations.ROBOTS`` and ``derivations.KERNEL_SETS`` is found
by introspection of its generated numpy module (the functions it defines, their positional
arguments, and the shape ``(..., n)`` each argument's docstring line gives), so a kernel added
later is fuzzed without a change here.  The properties:

- FK(IK(x)) = x: targets made by ``task`` from joints drawn inside ``LIMITS`` (edges and
  multiples of pi/2 included) have a valid branch, every valid branch lands on the target, and
  the generating configuration is among the branches where the task fixes every joint;
- the task is the test's own DH product (``tests/test_zoo.py``'s, from the description file);
- ``jacobian`` and ``task_jacobian`` are central differences of ``fk`` and ``task``;
- the rate maps give back the task rates they are given (joint_velocity, joint_acceleration and
  joint_velocity_from_twist against task_velocity, task_acceleration and twist), where regular;
- numpy and C agree on every kernel, batches and single points, to 1e-12 relative to each item's
  size with an absolute floor at the kernel's typical output size (the median item at random
  inputs), or they raise the same ValueError; looser only where the answer itself is: a rate
  map's damped solution at a singular configuration (2.2e-8), ik's joints where the target fixes
  them loosely (a double root, a wrist near its singularity: both answers on the target);
- any batch shape (empty ones too), broadcast arguments, strided, reversed, Fortran-ordered,
  zero-stride, unaligned, read-only, float32, float16, long double, integer, big-endian, list
  inputs, and a subclass of ndarray are converted exactly (the same bits as the call with the
  float64 C-contiguous copy), and bool, complex, object and string arrays are refused with a
  ValueError naming the kernel, alike in both backends;
- NaN and inf are refused with a ValueError naming them, or (ik, within_limits) reported per item
  as not valid, alike in both backends.

The expected values are the test's own (a round trip, differences of ``fk``, a DH product, the
same call on a float64 copy), never a kernel's output at the same point.  Examples are drawn by
the profile tests/conftest.py loads: HYPOTHESIS_PROFILE=fuzz (``make fuzz``) for the long run.
"""
from __future__ import annotations

import functools
import inspect
import math
import re
import warnings

import numpy as np
import pytest
from hypothesis import event, given, note, settings
from hypothesis import strategies as st

import derivations
import generated
from test_zoo import fk as dh_fk
from test_zoo import read_arm

pytestmark = pytest.mark.fuzz

BACKENDS = ("numpy", "c")
PACKAGES = [*derivations.ROBOTS, *derivations.KERNEL_SETS]
ROBOTS = list(derivations.ROBOTS)
DESCRIBED = {name: read_arm(path) for name, path in derivations.ROBOTS.items() if path.suffix == ".toml"}

EPS = np.finfo(float).eps
RTOL = 1e-12                 # numpy against C, and a batch item against its single call
ROUND_TRIP = 1e-9            # FK(IK(x)) against x, relative to max(1, |x|)
DOUBLE_ROOT = 1e-6           # joints of two roundings of a double root (the README's sqrt(eps) gap)
FD_STEP, FD_TOLERANCE = 1e-6, 1e-7
# The inverse rate maps solve J qd = xd; where J is flagged singular they damp it, and the
# answer then depends on singular values at rounding level: up to cond^2 eps with the damping's
# condition limit 1e4 (2.2e-8; the largest seen is 2e-9).
SOLVES = {"joint_velocity", "joint_acceleration", "joint_velocity_from_twist"}
DAMPED_RTOL = 1e4 ** 2 * EPS
ANGLES = {"phi", "T"}        # task coordinates that are angles (differences wrapped)
LENGTHS = {"x", "y", "z", "R", "Z"}
SPACES = ("joint", "motor", "tool", "cartesian")  # the AVR 3000's position spaces
SPECIAL_ANGLES = (0.0, math.pi / 2, -math.pi / 2, math.pi, -math.pi, math.pi / 4)


def load(name, backend="numpy"):
    return generated.load(name, backend=backend)


# --------------------------------------------------------------------------- kernels by introspection

# Not kernels of one evaluation: joint_vector reorders named positions, and ik_numeric iterates
# (two backends may take different steps within rounding and land on different solutions);
# tests/ik/test_numeric_ik.py holds them to their own properties.
ITERATIVE = {"joint_vector", "ik_numeric"}
_ARGUMENT = re.compile(r"^\s*(\w+): .*?shape \(\.\.\., (\d+)\)", re.M)


@functools.cache
def signatures(name) -> dict[str, tuple[tuple[str, int], ...]]:
    """{kernel: ((argument, size), ...)} of a package: the public functions its numpy module defines."""
    module = load(name)
    found = {}
    for kernel, function in vars(module).items():
        if kernel.startswith("_") or not inspect.isfunction(function) or function.__module__ != module.__name__:
            continue
        if kernel in ITERATIVE:
            continue
        positional = [p.name for p in inspect.signature(function).parameters.values()
                      if p.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD]
        sizes = {"q": str(len(module.JOINTS))} if kernel == "within_limits" else dict(_ARGUMENT.findall(function.__doc__))
        found[kernel] = tuple((argument, int(sizes[argument])) for argument in positional)
    return found


@pytest.mark.parametrize("name", PACKAGES)
def test_both_backends_have_the_same_kernels_and_keywords(name):
    """What the properties below fuzz: every kernel, each argument's size read from its docstring;
    the C module offers the same kernels with the same signatures."""
    kernels = signatures(name)
    assert set(kernels) - {"within_limits"} == set(load(name).OPERATIONS)  # every kernel the package counts
    assert all(arguments for arguments in kernels.values())
    numpy_module, c_module = load(name), load(name, "c")
    for kernel in kernels:
        expected = inspect.signature(getattr(numpy_module, kernel))
        assert inspect.signature(getattr(c_module, kernel)).parameters.keys() == expected.parameters.keys()
        keywords = [p.name for p in expected.parameters.values() if p.kind is inspect.Parameter.KEYWORD_ONLY]
        assert keywords == ([] if kernel == "within_limits" else list(numpy_module.PARAMS)), kernel
    if name in ROBOTS:
        assert {"fk", "frames", "jacobian", "task", "task_jacobian", "ik", "within_limits"} <= set(kernels)


# --------------------------------------------------------------------------- inputs

def joint_range(kind, limit):
    if limit is not None:
        return limit
    return (-math.pi, math.pi) if kind == "R" else (-1.0, 1.0)


@st.composite
def joint_values(draw, module, count):
    """(count, n) joint values within LIMITS (or +-pi, +-1 m), the edges and multiples of pi/2 likely."""
    columns = []
    for kind, limit in zip(module.JOINT_TYPES, module.LIMITS):
        low, high = joint_range(kind, limit)
        specials = [v for v in (*SPECIAL_ANGLES, low, high) if low <= v <= high] if kind == "R" else [low, high]
        value = st.one_of(st.floats(low, high), st.sampled_from(specials))
        columns.append(draw(st.lists(value, min_size=count, max_size=count)))
    return np.array(columns, dtype=float).T.reshape(count, len(columns))


def scaled_targets(module, x, factors):
    """Task coordinates with their lengths multiplied by ``factors`` (one per item): some unreachable."""
    x = x.copy()
    lengths = [i for i, t in enumerate(module.TASK) if t in LENGTHS]
    x[:, lengths] *= np.asarray(factors)[:, None]
    return x


@st.composite
def parameters(draw, name):
    """{} (the defaults, the fast path) or every parameter moved: x0.5 .. x1.5, or 0 .. 0.1 for a zero."""
    defaults = load(name).PARAMS
    if not defaults or draw(st.booleans()):
        return {}
    return {p: (v * draw(st.floats(0.5, 1.5)) if v else draw(st.floats(0.0, 0.1))) for p, v in defaults.items()}


GENERIC = st.one_of(st.floats(-3.0, 3.0), st.sampled_from([0.0, 1.0, -1.0, 0.5, 2.0]))


@st.composite
def argument_values(draw, name, argument, size, count, params):
    """(count, size) values for one argument, where the kernel is defined when possible: joints
    within the limits, targets made by ``task`` and AVR 3000 positions made from joints (some
    scaled out of reach or to 0: the origin, the T axis), anything else in -3 .. 3."""
    module = load(name)
    if argument in ("q", "joint") and module.JOINTS:
        return draw(joint_values(module, count))
    factors = st.lists(st.sampled_from([1.0, 1.0, 1.0, 0.5, 3.0, 0.0]), min_size=count, max_size=count)
    if argument == "x" and module.TASK:
        q = draw(joint_values(module, count))
        return scaled_targets(module, module.task(q, **params), draw(factors, label="scaled by"))
    if argument in SPACES and hasattr(module, f"joint_to_{argument}"):
        values = getattr(module, f"joint_to_{argument}")(draw(joint_values(module, count)), **params)
        return values * np.array(draw(factors, label="scaled by"))[:, None]
    return np.array(draw(st.lists(GENERIC, min_size=count * size, max_size=count * size))).reshape(count, size)


def reference_values(name, argument, size, count, rng):
    """The same kinds of values as argument_values, from a seeded generator (the floors below)."""
    module = load(name)
    if argument in ("q", "joint", "x", *SPACES) and module.JOINTS:
        bounds = [joint_range(kind, limit) for kind, limit in zip(module.JOINT_TYPES, module.LIMITS)]
        q = rng.uniform(*np.array(bounds).T, (count, len(bounds)))
        if argument == "x" and module.TASK:
            return module.task(q)
        if argument in SPACES and hasattr(module, f"joint_to_{argument}"):
            return getattr(module, f"joint_to_{argument}")(q)
        if argument in ("q", "joint"):
            return q
    return rng.uniform(-3.0, 3.0, (count, size))


def call(function, args, params=None):
    """A kernel's outputs as a tuple, or the exception it raised (numpy's RuntimeWarnings aside);
    ``params`` go to the kernels that take them (within_limits takes none)."""
    if function.__name__ == "within_limits":
        params = None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            result = function(*args, **(params or {}))
    except Exception as exc:  # compared below: both backends must raise alike
        return exc
    return result if isinstance(result, tuple) else (result,)


@functools.cache
def floors(name, kernel) -> tuple[float, ...]:
    """Per output of a kernel, its typical size: the median over 64 random items (numpy backend,
    default parameters) of the item's largest finite magnitude; 1 where nothing is finite."""
    rng = np.random.default_rng(17)
    args = [reference_values(name, a, s, 64, rng) for a, s in signatures(name)[kernel]]
    function = getattr(load(name), kernel)
    items = [call(function, [a[i] for a in args]) for i in range(64)]
    items = [item for item in items if not isinstance(item, Exception)]
    result = []
    for index in range(len(items[0]) if items else 0):
        sizes = [np.abs(v[np.isfinite(v)]).max() for v in (np.asarray(item[index], float) for item in items)
                 if np.isfinite(v).any()]
        result.append(float(np.median(sizes)) if sizes and np.median(sizes) > 0 else 1.0)
    return tuple(result)


# --------------------------------------------------------------------------- comparing outcomes

def describe(outcome):
    if isinstance(outcome, Exception):
        return f"{type(outcome).__name__}: {outcome}"
    return f"outputs of shapes {[np.shape(o) for o in outcome]}"


def wrapped(difference):
    return np.abs((difference + np.pi) % (2 * np.pi) - np.pi)


def assert_same_refusal(name, kernel, a, b):
    """Both backends raised the same ValueError subclass (the AVR 3000's UnreachableError and
    SingularError are two), its message naming the kernel."""
    assert isinstance(a, Exception) and isinstance(b, Exception), (
        f"{name}.{kernel}: numpy {describe(a)}; C {describe(b)}")
    assert isinstance(a, ValueError) and type(a) is type(b), f"{name}.{kernel}: numpy {describe(a)}; C {describe(b)}"
    for error in (a, b):  # every refusal names the kernel
        assert str(error).startswith(f"{kernel}:"), describe(error)


def assert_outputs_agree(name, kernel, a, b, count, params, target=None, rtol=RTOL):
    """Outputs of one kernel at the same inputs (``count`` items), numpy (``a``) against C (``b``),
    or a batch against its items: equal shapes, dtypes and flags, and floats within ``rtol`` of
    each item's largest magnitude (at least the kernel's floor); NaN where the other has NaN."""
    assert len(a) == len(b), (len(a), len(b))
    for x, y in zip(a, b):
        assert x.shape == y.shape and x.dtype == y.dtype, (name, kernel, x.shape, y.shape, x.dtype, y.dtype)
        if x.dtype == bool:
            assert np.array_equal(x, y), f"{name}.{kernel}: flags differ: {x} / {y}"
    module = load(name)
    flags = [o for o in a if o.dtype == bool]
    for index, (x, y) in enumerate(zip(a, b)):
        if x.dtype == bool:
            continue
        floor = floors(name, kernel)[index]
        x, y = x.reshape(count, -1), y.reshape(count, -1)
        if kernel == "ik":
            assert_ik_agrees(module, x, y, flags[0].reshape(count, -1), params, target)
            continue
        same = (x == y) | (np.isnan(x) & np.isnan(y))  # infinities and NaN only where both have them
        assert same[~(np.isfinite(x) & np.isfinite(y))].all(), f"{name}.{kernel}: NaN or inf in one backend only"
        x, y = np.where(same, 0.0, x), np.where(same, 0.0, y)
        scale = np.maximum(np.abs(x).max(axis=1), floor)
        error = np.abs(x - y).max(axis=1) / scale
        allowed = np.full(count, rtol)
        if kernel in SOLVES:  # damped where flagged singular (the flag is the kernel's last output)
            allowed = np.where(flags[-1].reshape(count), max(rtol, DAMPED_RTOL), rtol)
        worst = int(np.argmax(error / allowed))
        assert error[worst] <= allowed[worst], (
            f"{name}.{kernel} output {index}: item {worst} differs by {error[worst]:.3g} relative "
            f"(allowed {allowed[worst]:.3g}, floor {floor:.3g}): {x[worst]} / {y[worst]}")


def assert_ik_agrees(module, x, y, valid, params, target):
    """ik's joints on the branches valid in both: within RTOL (revolute modulo 2 pi); or, where the
    task Jacobian is singular to 1e-4 (a double root, a wrist near its singularity), within what the
    target fixes them to, max(DOUBLE_ROOT, 1e3 eps / (its smallest singular value relative to its
    largest)), with both answers on the target."""
    n = len(module.JOINTS)
    Qa, Qb = x.reshape(len(x), -1, n), y.reshape(len(y), -1, n)
    difference = np.abs(Qa - Qb)
    revolute = [i for i, kind in enumerate(module.JOINT_TYPES) if kind == "R"]
    difference[..., revolute] = wrapped(Qa - Qb)[..., revolute]
    difference = np.where(valid[..., None], difference, 0.0).max(axis=-1)
    close = difference <= RTOL * np.maximum(1.0, np.abs(np.where(valid[..., None], Qa, 0.0)).max(axis=-1))
    for item, branch in zip(*np.nonzero(~close)):
        qa, qb = Qa[item, branch], Qb[item, branch]
        singular_values = np.linalg.svd(module.task_jacobian(qa, **params), compute_uv=False)
        ratio = singular_values[-1] / singular_values[0]
        assert difference[item, branch] <= max(DOUBLE_ROOT, 1e3 * EPS / ratio) and ratio <= 1e-4, (
            f"{module.NAME}.ik item {item} branch {module.BRANCHES[branch]}: joints {qa} / {qb} "
            f"(singular values of the task Jacobian {singular_values})")
        for q in (qa, qb):
            assert task_distance(module, module.task(q, **params), target[item]).max() <= ROUND_TRIP
        event("ik: joints fixed loosely by the target (a double root or near a singularity)")


def task_distance(module, x, target):
    """|x - target| per coordinate, angles modulo 2 pi, relative to max(1, |target|)."""
    difference = np.abs(np.asarray(x) - target)
    for i, t in enumerate(module.TASK):
        if t in ANGLES:
            difference[..., i] = wrapped(np.asarray(x)[..., i] - target[..., i])
    return difference / np.maximum(1.0, np.abs(target).max(axis=-1, keepdims=True))


# --------------------------------------------------------------------------- properties: kinematics

@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", list(DESCRIBED))
@given(data=st.data())
def test_fk_and_task_are_the_dh_product_of_the_description(name, backend, data):
    """fk and task at joints within the limits against tests/test_zoo.py's DH product of the
    robot's description file (pose task: position then rotation rows; phi: atan2 of the rotation)."""
    module, arm = load(name, backend), DESCRIBED[name]
    q = data.draw(joint_values(load(name), data.draw(st.integers(1, 4))), label="q")
    T = dh_fk(arm, q)
    assert np.abs(module.fk(q) - T).max() <= 1e-12 * max(1.0, np.abs(T).max())
    expected = {"x": T[:, 0, 3], "y": T[:, 1, 3], "z": T[:, 2, 3], "phi": np.arctan2(T[:, 1, 0], T[:, 0, 0])}
    expected.update({f"r{i + 1}{j + 1}": T[:, i, j] for i in range(3) for j in range(3)})
    x = np.stack([expected[t] for t in module.TASK], axis=-1)
    assert task_distance(module, module.task(q), x).max() <= 1e-12


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ROBOTS)
@given(data=st.data())
def test_fk_of_ik_is_the_target(name, backend, data):
    """x = task(q) for q within the limits: some branch is valid, every valid branch's task is x
    (to 1e-9), and q itself is among the branches (modulo 2 pi, to 1e-6) wherever x fixes every
    joint; a Puma target given as a 4x4 pose gives the same answer as its 12 numbers."""
    module = load(name, backend)
    q = data.draw(joint_values(module, data.draw(st.integers(1, 4))), label="q")
    if name == "scorbot_er7" and data.draw(st.booleans(), label="gripper horizontal"):
        q[:, 3] = -(q[:, 1] + q[:, 2])  # the configurations ik returns: theta4 = -(theta2 + theta3)
    x = module.task(q)
    Q, valid = module.ik(x)
    k, n = len(module.BRANCHES), len(module.JOINTS)
    assert Q.shape == (len(q), k, n) and valid.shape == (len(q), k)
    determined = determined_configurations(name, q)
    reachable = valid.any(axis=-1) | (~determined if name == "scorbot_er7" else False)
    assert reachable.all(), f"no valid branch for q = {q[~reachable]}"
    reached = module.task(np.where(valid[..., None], Q, 0.0))
    miss = np.where(valid, task_distance(module, reached, x[:, None, :]).max(axis=-1), 0.0)
    assert miss.max() <= ROUND_TRIP, f"a valid branch misses by {miss.max():.3g}: {Q[miss > ROUND_TRIP]}"
    assert np.isfinite(Q[valid]).all()
    revolute = [i for i, kind in enumerate(module.JOINT_TYPES) if kind == "R" and (name, i) not in NOT_WRAPPED]
    assert (np.abs(Q[valid][:, revolute]) <= np.pi).all(), f"ik's revolute joints not in (-pi, pi]: {Q[valid]}"
    unwrapped = [i for i in range(n) if (name, i) in NOT_WRAPPED]
    assert ((Q[valid][:, unwrapped] >= 0) & (Q[valid][:, unwrapped] <= 2 * np.pi)).all(), Q[valid]
    distance = np.where(valid, generating_distance(name, q, Q), np.inf).min(axis=-1)
    assert (distance[determined] <= DOUBLE_ROOT).all(), (
        f"the generating configuration is not among the branches: q = {q[determined][distance[determined] > DOUBLE_ROOT]}")
    if "r11" in module.TASK:
        pose = np.zeros((len(x), 4, 4))
        pose[:, :3, 3], pose[:, :3, :3], pose[:, 3, 3] = x[:, :3], x[:, 3:].reshape(-1, 3, 3), 1.0
        Q4, valid4 = module.ik(pose)
        assert np.array_equal(valid4, valid) and np.array_equal(Q4, Q, equal_nan=True)


# Joints ik leaves in [0, 2 pi] instead of (-pi, pi]: the AVR 3000's q2 = 2 acos(R / 2a), as its
# docstring says (the property found it, when every ik docstring said (-pi, pi]).
NOT_WRAPPED = {("avr3000", 1)}


def test_the_avr3000_ik_docstring_says_where_q2_lies():
    for backend in BACKENDS:
        Q, valid = load("avr3000", backend).ik(load("avr3000").task([0.0, 4.0, 0.0]))
        assert valid.all() and Q[0, 1] == pytest.approx(4.0, abs=1e-12)
    assert "[0, 2 pi]" in load("avr3000").ik.__doc__ and "(-pi, pi]" in load("avr3000").ik.__doc__


def determined_configurations(name, q):
    """Where the task fixes every joint (so q must come back): not with the R-P arm's slider at 0
    (q1 free), nor a SCORBOT whose gripper is not horizontal (ik sets theta4 = -(theta2 + theta3),
    theta5 = 0: the wrist's pitch and roll are not in its position task, and its branches reach
    only the points a horizontal gripper reaches)."""
    if name == "planar_rp":
        return np.abs(q[:, 1]) > 1e-9
    if name == "scorbot_er7":
        return np.abs(wrapped(q[:, 3] + q[:, 1] + q[:, 2])) <= 1e-12
    return np.ones(len(q), dtype=bool)


# Near the Puma's wrist singularity the pose fixes q4 and q6 apart only to about eps / |sin q5|
# (found by the fuzz: q5 = 3e-12 gives q4 off by 2e-5, its sum with q6 exact): below this they
# are compared by their sum.
WRIST_SINGULAR = 1e-8


def generating_distance(name, q, Q):
    """max |Q - q| per branch (revolute joints modulo 2 pi), up to what the task leaves free: the
    SCORBOT's roll theta5; at or near the Puma's wrist singularity (|sin q5| <= WRIST_SINGULAR)
    q4 + q6 (q5 near 0) or q6 - q4 (near pi) only."""
    module = load(name)
    difference = np.abs(Q - q[:, None, :])
    for i, kind in enumerate(module.JOINT_TYPES):
        if kind == "R":
            difference[..., i] = wrapped(Q[..., i] - q[:, None, i])
    if name == "scorbot_er7":
        difference[..., 4] = 0.0
    if name == "puma560":
        singular = np.abs(np.sin(q[:, 4])) <= WRIST_SINGULAR
        sign = np.where(np.cos(q[:, 4]) > 0, 1.0, -1.0)[:, None]
        free = wrapped(Q[..., 5] + sign * Q[..., 3] - (q[:, None, 5] + sign * q[:, None, 3]))
        difference[singular, :, 3] = free[singular]
        difference[singular, :, 5] = 0.0
    return difference.max(axis=-1)


def central_differences(function, q, wrap_columns=()):
    """d function / d q_j by central differences, stacked on a last axis of size n."""
    columns = []
    for j in range(q.shape[-1]):
        step = np.zeros(q.shape[-1])
        step[j] = FD_STEP
        difference = function(q + step) - function(q - step)
        for c in wrap_columns:
            difference[..., c] = (difference[..., c] + np.pi) % (2 * np.pi) - np.pi
        columns.append(difference / (2 * FD_STEP))
    return np.stack(columns, axis=-1)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ROBOTS)
@given(data=st.data())
def test_jacobians_are_central_differences_of_fk_and_task(name, backend, data):
    """jacobian = [dp/dq; vee(dR/dq R^T)] and task_jacobian = d task/dq by central differences
    (step 1e-6, within 1e-7 of max(1, |J|)), at any joints, with parameters moved or not."""
    module = load(name, backend)
    params = data.draw(parameters(name), label="params")
    q = data.draw(joint_values(module, data.draw(st.integers(1, 3))), label="q")
    T = module.fk(q, **params)
    dT = central_differences(lambda v: module.fk(v, **params), q)             # (..., 4, 4, n)
    omega = np.einsum("...ikn,...jk->...ijn", dT[..., :3, :3, :], T[..., :3, :3])  # dR/dq R^T
    expected = np.concatenate([dT[..., :3, 3, :], np.stack([omega[..., 2, 1, :], omega[..., 0, 2, :],
                                                            omega[..., 1, 0, :]], axis=-2)], axis=-2)
    J = module.jacobian(q, **params)
    assert np.abs(J - expected).max() <= FD_TOLERANCE * max(1.0, np.abs(J).max())
    angles = [i for i, t in enumerate(module.TASK) if t in ANGLES]
    expected = central_differences(lambda v: module.task(v, **params), q, angles)
    Jx = module.task_jacobian(q, **params)
    assert np.abs(Jx - expected).max() <= FD_TOLERANCE * max(1.0, np.abs(Jx).max())


RATE_MAPS = [name for name in ROBOTS if "joint_acceleration" in signatures(name)]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", RATE_MAPS)
@given(data=st.data())
def test_the_rate_maps_give_back_the_task_rates_they_are_given(name, backend, data):
    """xd = task_velocity(q, qd): the joint rates joint_velocity(q, xd) move the task at xd (to 1e-9
    of max(1, |xd|)) wherever it does not flag the configuration singular; the same of
    joint_acceleration and task_acceleration, and of joint_velocity_from_twist and twist."""
    module = load(name, backend)
    params = data.draw(parameters(name), label="params")
    count = data.draw(st.integers(1, 3))
    q = data.draw(joint_values(module, count), label="q")
    qd, qdd = (data.draw(argument_values(name, label, len(module.JOINTS), count, params), label=label)
               for label in ("qd", "qdd"))
    maps = [("task_velocity", "joint_velocity", (q,), qd), ("task_acceleration", "joint_acceleration", (q, qd), qdd)]
    if "joint_velocity_from_twist" in signatures(name):
        maps.append(("twist", "joint_velocity_from_twist", (q,), qd))
    for forward, inverse, state, rates in maps:
        x = getattr(module, forward)(*state, rates, **params)
        back, singular = getattr(module, inverse)(*state, x, **params)
        miss = np.abs(getattr(module, forward)(*state, back, **params) - x).max(axis=-1)
        miss = miss / np.maximum(1.0, np.abs(x).max(axis=-1))
        assert (miss[~singular] <= ROUND_TRIP).all(), f"{inverse}: misses {forward} by {miss[~singular].max():.3g}"


# --------------------------------------------------------------------------- properties: the two backends

BATCHES = st.sampled_from([(), (1,), (2,), (3,), (2, 2)])


@st.composite
def kernel_inputs(draw, name, batch=None):
    """(batch, params, {(argument, size): values of shape batch + (size,)}) for every argument of the package."""
    batch = draw(BATCHES) if batch is None else batch
    params = draw(parameters(name), label="params")
    count = math.prod(batch)
    values = {}
    for arguments in signatures(name).values():
        for argument, size in arguments:
            if (argument, size) not in values:  # (the trajectories' boundary has 5 or 7 numbers)
                values[argument, size] = draw(argument_values(name, argument, size, count, params),
                                              label=argument).reshape(batch + (size,))
    return batch, params, values


def task_targets(name, values, batch):
    """The drawn ik targets as (count, m) (m = 0 for a package without a task)."""
    m = len(load(name).TASK)
    return values.get(("x", m), np.zeros(batch + (0,))).reshape(math.prod(batch), -1)


def items(args, count):
    return [[a.reshape(count, -1)[i] for a in args] for i in range(count)]


@pytest.mark.parametrize("name", PACKAGES)
@settings(max_examples=max(2, settings.default.max_examples // 2))
@given(data=st.data())
def test_numpy_and_c_agree_on_every_kernel(name, data):
    """Each kernel of the package on the same drawn batch in both backends, and each item of the
    batch on its own: the same outputs to 1e-12 (see assert_outputs_agree), or the same ValueError."""
    batch, params, values = data.draw(kernel_inputs(name))
    count = math.prod(batch)
    numpy_module, c_module = load(name), load(name, "c")
    for kernel, arguments in signatures(name).items():
        args = [values[argument] for argument in arguments]
        note(f"{kernel}{tuple(a.tolist() for a in args)} {params}")
        a, b = call(getattr(numpy_module, kernel), args, params), call(getattr(c_module, kernel), args, params)
        if isinstance(a, Exception) or isinstance(b, Exception):
            assert_same_refusal(name, kernel, a, b)
            continue
        singles = [[call(getattr(m, kernel), item, params) for item in items(args, count)]
                   for m in (numpy_module, c_module)]
        target = task_targets(name, values, batch)
        assert_outputs_agree(name, kernel, a, b, count, params, target)
        for i, (single_a, single_b) in enumerate(zip(*singles)):
            for whole, single in ((a, single_a), (b, single_b)):
                assert not isinstance(single, Exception), f"{name}.{kernel}: item {i} alone: {describe(single)}"
                assert_outputs_agree(name, kernel, tuple(o.reshape((count,) + o.shape[len(batch):])[i] for o in whole),
                                     single, 1, params, target[i:i + 1])


def test_a_mixed_avr3000_batch_raises_the_same_error_in_both_backends():
    """An unreachable target first and a singular one after: the first failing item's error in both
    backends (numpy used to look for every singular item before any unreachable one)."""
    x = np.array([[1.0, 1.0, 0.0], [0.0, 0.0, 0.0]])
    for backend in BACKENDS:
        for batch, kind in ((x, "UnreachableError"), (x[::-1], "SingularError")):
            with pytest.raises(ValueError, match=r"at batch index \(0,\)") as info:
                load("avr3000", backend).cartesian_to_joint(batch)
            assert type(info.value).__name__ == kind, (backend, describe(info.value))


# --------------------------------------------------------------------------- properties: input forms

def _subclass(a):
    return a.view(type("Sub", (np.ndarray,), {}))


def _unaligned(a):
    if a.size == 0:
        return a
    raw = np.empty(a.size * 8 + 1, dtype=np.uint8)
    out = np.frombuffer(raw[1:].data, dtype=np.float64, count=a.size).reshape(a.shape)
    out[...] = a
    return out


def _read_only(a):
    a = a.copy()
    a.setflags(write=False)
    return a


# How an argument may arrive.  Each numeric form must give the bits of the call with the float64
# C-contiguous copy of np.asarray(form); the last four must be refused with a ValueError.
FORMS = {
    "list": lambda a: a.tolist(),
    "float32": lambda a: a.astype(np.float32),
    "float16": lambda a: a.astype(np.float16),
    "longdouble": lambda a: a.astype(np.longdouble),
    "int64": lambda a: np.round(a).astype(np.int64),
    "int8": lambda a: np.round(a).astype(np.int8),
    "uint16": lambda a: np.abs(np.round(a)).astype(np.uint16),
    "big_endian": lambda a: a.astype(">f8"),
    "read_only": _read_only,
    "fortran": lambda a: np.asfortranarray(a),
    "strided": lambda a: np.repeat(a, 3, axis=-1)[..., ::3],
    "reversed": lambda a: np.ascontiguousarray(a[..., ::-1])[..., ::-1],
    "zero_stride": lambda a: np.broadcast_to(a, (2,) + a.shape),
    "unaligned": _unaligned,
    "subclass": _subclass,
    "bool": lambda a: a > 0,
    "complex": lambda a: a.astype(complex),
    "object": lambda a: a.astype(object),
    "string": lambda a: a.astype(str),
}
REFUSED = ("bool", "complex", "object", "string")


@pytest.mark.parametrize("name", PACKAGES)
@given(data=st.data())
def test_inputs_of_any_batch_shape_and_layout(name, data):
    """One kernel, its arguments of one batch shape (empty ones too) or broadcast from fewer
    dimensions, one argument in a drawn form (FORMS): both backends give exactly what they give
    for the float64 C-contiguous copy, of shape batch + the kernel's own, or both refuse a
    non-real dtype with a ValueError naming the kernel."""
    kernel = data.draw(st.sampled_from(sorted(signatures(name))), label="kernel")
    arguments = signatures(name)[kernel]
    batch = data.draw(st.sampled_from([(), (1,), (3,), (0,), (2, 0), (2, 3), (1, 2, 2)]), label="batch")
    _, params, values = data.draw(kernel_inputs(name, batch if math.prod(batch) else (1,)))
    args = []
    for argument, size in arguments:
        value = values[argument, size] if math.prod(batch) else np.zeros(batch + (size,))
        if value.ndim > 1 and data.draw(st.booleans(), label=f"{argument} broadcast"):
            value = values[argument, size].reshape(-1, size)[0]  # one item, broadcast against the others
        args.append(value)
    which = data.draw(st.integers(0, len(args) - 1), label="argument")
    form = data.draw(st.sampled_from(sorted(FORMS) + (["pose"] if kernel == "ik" and name == "puma560" else [])),
                     label="form")
    formed = list(args)
    if form == "pose":
        x = args[which]
        pose = np.zeros(x.shape[:-1] + (4, 4))
        pose[..., :3, 3], pose[..., :3, :3], pose[..., 3, 3] = x[..., :3], x[..., 3:].reshape(x.shape[:-1] + (3, 3)), 1.0
        formed[which] = pose
    else:
        with np.errstate(over="ignore", invalid="ignore"):  # float16 and int8 of large values: inf, wrapped
            formed[which] = FORMS[form](args[which])
    reference = list(args)
    if form not in REFUSED and form != "pose":
        reference[which] = np.ascontiguousarray(np.asarray(formed[which]), dtype=np.float64)
    try:
        shape = np.broadcast_shapes(*(np.shape(r)[:-1] for r in reference))
    except ValueError:  # a zero-stride form's new axis against another batch: both must refuse
        shape = None
    outcomes = {}
    for backend in BACKENDS:
        function = getattr(load(name, backend), kernel)
        got, expected = call(function, formed, params), call(function, reference, params)
        outcomes[backend] = got
        if form in REFUSED:
            assert isinstance(got, ValueError) and str(got).startswith(f"{kernel}:"), describe(got)
            continue
        if isinstance(expected, Exception):
            assert type(got) is type(expected), f"{backend}: {describe(got)}; float64 copy: {describe(expected)}"
            continue
        assert not isinstance(got, Exception) and shape is not None, f"{backend} {form}: {describe(got)}"
        for g, e in zip(got, expected):
            assert type(g) is np.ndarray and g.shape == e.shape and g.shape[:len(shape)] == shape, (g.shape, e.shape)
            assert g.dtype == e.dtype and np.array_equal(g, e, equal_nan=True), f"{backend} {form}: {g} / {e}"
    if not all(isinstance(o, Exception) for o in outcomes.values()):
        return
    assert_same_refusal(name, kernel, outcomes["numpy"], outcomes["c"])


@pytest.mark.parametrize("name", PACKAGES)
@given(data=st.data())
def test_nan_and_inf_are_refused_or_reported_alike(name, data):
    """NaN, inf or -inf in some items of one argument: a ValueError saying so from both backends,
    or (ik, within_limits, which take them) not valid at exactly those items and the same answer
    elsewhere as without them; an empty batch beside a non-finite argument alike in both."""
    kernel = data.draw(st.sampled_from(sorted(signatures(name))), label="kernel")
    arguments = signatures(name)[kernel]
    batch, params, values = data.draw(kernel_inputs(name, data.draw(st.sampled_from([(1,), (3,), (2, 2)]))))
    count = math.prod(batch)
    args = [values[argument].copy() for argument in arguments]
    which = data.draw(st.integers(0, len(args) - 1), label="argument")
    bad = np.array(data.draw(st.lists(st.booleans(), min_size=count, max_size=count), label="bad items"))
    bad[data.draw(st.integers(0, count - 1))] = True
    flat = args[which].reshape(count, -1)
    for i in np.flatnonzero(bad):
        flat[i, data.draw(st.integers(0, flat.shape[1] - 1))] = data.draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    args[which] = flat.reshape(args[which].shape)
    if len(args) > 1 and data.draw(st.booleans(), label="empty beside"):
        # every other argument empty: the batch is empty, and the non-finite values never used
        args = [a if i == which else np.zeros((0,) + a.shape[-1:]) for i, a in enumerate(args)]
        args[which] = args[which].reshape(count, -1)[np.flatnonzero(bad)[:1]]
        count, bad = 0, bad[:0]
    outcomes = [call(getattr(load(name, b), kernel), args, params) for b in BACKENDS]
    note(f"{kernel}{tuple(a.tolist() for a in args)}: {[describe(o) for o in outcomes]}")
    if count == 0:
        assert type(outcomes[0]) is type(outcomes[1]), [describe(o) for o in outcomes]
        return
    for backend, outcome in zip(BACKENDS, outcomes):
        if isinstance(outcome, Exception):
            assert isinstance(outcome, ValueError) and "NaN or inf" in str(outcome), f"{backend}: {describe(outcome)}"
            assert str(outcome).startswith(f"{kernel}:"), describe(outcome)
        else:
            flags = [o.reshape(count, -1) for o in outcome if o.dtype == bool]
            assert flags and not any(f[bad].any() for f in flags), f"{backend}: a non-finite item reported valid"
    assert isinstance(outcomes[0], Exception) == isinstance(outcomes[1], Exception), [describe(o) for o in outcomes]
    if isinstance(outcomes[0], Exception) or bad.all():
        return
    clean = [a.reshape(count, -1)[~bad] if a.shape[:-1] == batch else a for a in args]
    for backend, outcome in zip(BACKENDS, outcomes):
        expected = call(getattr(load(name, backend), kernel), clean, params)
        got = tuple(o.reshape((count,) + o.shape[len(batch):])[~bad] for o in outcome)
        assert_outputs_agree(name, kernel, got, expected, int((~bad).sum()), params,
                             task_targets(name, values, batch)[~bad])
