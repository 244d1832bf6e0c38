"""The performance levers keep every result and every check: blocks, vector sin/cos, thin binding.

Speed itself is never asserted here (`make bench` measures it); these tests
check that the faster paths compute the same numbers and reject the same bad
input as the plain ones.
"""
import importlib
import inspect
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import derivations
import generated
from codegen import build, generate
from conftest import kernels
from test_properties import _ARGUMENT  # each argument's size, read from a kernel's docstring

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("kernel", ["fk", "frames", "jacobian", "task", "task_jacobian"])
def test_batches_across_block_boundaries_equal_single_calls(kernel):
    """Batches of 1, a partial block, exactly a block and several blocks against one call per pose.

    The built library's batches run vectorised (libmvec sin/cos, at most 4 ulp
    from the scalar libm), the single poses in scalar C: equal to 1e-14.
    """
    k = kernels("puma560", "c")
    rng = np.random.default_rng(3)
    for count in (1, 5, 63, 64, 65, 200):
        q = rng.uniform(-3, 3, (count, 6))
        batch = getattr(k, kernel)(q)
        single = np.stack([getattr(k, kernel)(qi) for qi in q])
        np.testing.assert_allclose(batch, single, rtol=0, atol=1e-14)


def test_nan_and_inf_are_caught_in_c_anywhere_in_a_batch():
    """The finiteness check runs in C, over every value, wherever the bad one is."""
    k = kernels("puma560", "c")
    q = np.zeros((1000, 6))
    for bad in (np.nan, np.inf, -np.inf):
        for where in ((0, 0), (517, 3), (999, 5)):
            q_bad = q.copy()
            q_bad[where] = bad
            with pytest.raises(ValueError, match="fk: q contains NaN or inf"):
                k.fk(q_bad)
            with pytest.raises(ValueError, match="jacobian: q contains NaN or inf"):
                k.jacobian(q_bad)
    assert np.isfinite(k.fk(q)).all()


@pytest.mark.parametrize("q", [
    np.zeros((4, 12))[:, ::2],  # not contiguous
    np.zeros((4, 6), dtype=np.float32),  # another dtype
    np.zeros((4, 6)).astype(">f8"),  # another byte order
    [[0.0] * 6] * 4,  # a list
    np.zeros((4, 6), dtype=np.int16),
])
def test_inputs_off_the_fast_path_give_the_same_results(q):
    k = kernels("puma560", "c")
    np.testing.assert_array_equal(k.fk(q), k.fk(np.zeros((4, 6))))


def _outputs(result):
    return [np.asarray(r, dtype=float) for r in (result if isinstance(result, tuple) else (result,))]


@pytest.mark.parametrize("name", ["puma560", "avr3000", "planar_rp", "scorbot_path"])
def test_each_one_point_front_hands_every_other_call_to_its_own_function(name):
    """A C kernel that takes one point is a built-in front (robot_point.c.j2) bound to the Python
    function of its name: every call form but the arrays alone (lists, a batch of one, the
    parameters spelled out at their default values, the arrays by keyword) reaches that function,
    whose answer must equal the front's own; and the front reads like the function it fronts."""
    numpy_module, c_module = kernels(name, "numpy"), kernels(name, "c")
    rng = np.random.default_rng(11)
    fronted = [kernel for kernel, f in vars(c_module).items() if inspect.isbuiltin(f) and not kernel.startswith("_")]
    assert len(fronted) >= 2
    for kernel in fronted:
        front = getattr(c_module, kernel)
        signature = inspect.signature(getattr(numpy_module, kernel))
        assert inspect.signature(front).parameters.keys() == signature.parameters.keys(), kernel
        assert front.__module__ == c_module.__name__ and front.__name__ == kernel
        assert "(C backend)" in front.__doc__
        positional = [p.name for p in signature.parameters.values() if p.kind is p.POSITIONAL_OR_KEYWORD]
        sizes = dict(_ARGUMENT.findall(getattr(numpy_module, kernel).__doc__))
        point = [rng.uniform(-0.5, 0.5, int(sizes.get(a, len(numpy_module.JOINTS)))) for a in positional]
        if kernel.startswith("ik"):  # a reachable target (a pose: a rigid transform), the seed near it
            q = rng.uniform(-0.5, 0.5, len(numpy_module.JOINTS))
            point[0] = numpy_module.task(q)
            if kernel == "ik_numeric":
                point[1] = q + 0.05
        fast = _outputs(front(*point))
        spelled = {p: float(repr(getattr(c_module, "_" + p))) for p in numpy_module.PARAMS}  # not the default objects
        for other in (front(*[a.tolist() for a in point]), front(*point, **spelled),
                      front(**dict(zip(positional, point)))):
            for got, expected in zip(_outputs(other), fast, strict=True):
                np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12, err_msg=kernel)
        for got, expected in zip(_outputs(front(*[a[None] for a in point])), fast, strict=True):
            np.testing.assert_allclose(got[0], expected, rtol=0, atol=1e-12, err_msg=kernel)
        with pytest.raises(TypeError, match=kernel):
            front(*point, no_such_parameter=1.0)


def test_parameters_off_the_default_are_checked_and_cached_by_value():
    k = kernels("puma560", "c")
    q = np.random.default_rng(4).uniform(-1, 1, (3, 6))
    longer = k.fk(q, a2=0.5)
    assert not np.allclose(longer, k.fk(q))
    np.testing.assert_array_equal(k.fk(q, a2=0.5), longer)  # from the cache
    np.testing.assert_array_equal(k.fk(q, a2=np.float64(0.5)), longer)
    np.testing.assert_array_equal(k.fk(q, a2=np.array(0.5)), longer)
    np.testing.assert_array_equal(k.fk(q, a2=1), k.fk(q, a2=1.0))
    # A bool equals 1.0 and hashes like it, so the cache must not let it through.
    k.fk(q, d1=1.0)
    with pytest.raises(ValueError, match="parameter d1 must be a real number, got bool"):
        k.fk(q, d1=True)
    with pytest.raises(ValueError, match="parameter d1 must be finite"):
        k.fk(q, d1=float("nan"))
    np.testing.assert_array_equal(k.fk(q, d1=0.67183), k.fk(q))  # an equal value, not the default object


def test_adept_three_defaults_of_zero_are_not_taken_by_false():
    k = kernels("adept_three", "c")
    with pytest.raises(ValueError, match="parameter d4 must be a real number, got bool"):
        k.fk(np.zeros(4), d4=False)


def test_the_built_library_uses_the_fast_flags_only_when_asked_and_they_work(monkeypatch):
    """Portable C99 -O2 by default (a package that runs on any CPU of its kind, compiled in seconds);
    the vectorised layout for this machine when asked (`make build`, `generate --fast`), unless
    KINEGEN_PORTABLE=1 says otherwise."""
    monkeypatch.delenv("KINEGEN_OPT", raising=False)  # make test's -O0
    script = build.load_build_script(generate.GENERATED / "puma560")
    assert script.compile_flags() == ["-std=c99", "-O2", "-fno-math-errno"]
    flags = script.compile_flags(fast=True)
    assert flags[:4] == ["-std=c99", "-O2", "-fno-math-errno", "-O3"] and "-march=native" in flags
    assert "-DKINEGEN_SIMD" in flags
    assert "-ffast-math" not in flags and "-ffinite-math-only" not in flags
    for env in ({"KINEGEN_PORTABLE": "1", "KINEGEN_FAST": "1"}, {}):
        portable = subprocess.run(
            [sys.executable, "-c", "import runpy; print(runpy.run_path('build_c.py')['compile_flags']())"],
            cwd=generate.GENERATED / "puma560", capture_output=True, text=True, check=True,
            env={**env, "PATH": "/usr/bin:/bin"})
        assert portable.stdout.strip() == "['-std=c99', '-O2', '-fno-math-errno']"


def test_kinegen_opt_sets_the_portable_level_and_a_bad_one_is_refused_before_work(monkeypatch, tmp_path, capsys):
    """KINEGEN_OPT (make test's -O0) sets the level of the portable build, not of the vectorised
    one (its -O3 comes last) nor of the cffi binding (always -O0); anything but -O0..-O3/-Os is refused: by
    build_c.py itself, and by `kinegen generate` and `build` at once, exit 2, nothing written."""
    script = build.load_build_script(generate.GENERATED / "planar_2r")
    monkeypatch.setenv("KINEGEN_OPT", "-O1")
    assert script.compile_flags(fast=False) == ["-std=c99", "-O1", "-fno-math-errno"] and script.binding_flags() == ["-O0", "-g0"]
    fast = script.compile_flags(fast=True)
    assert fast == ["-std=c99", "-O1", "-fno-math-errno"] or fast[:4] == ["-std=c99", "-O2", "-fno-math-errno", "-O3"]  # (no SIMD here: portable)
    monkeypatch.setenv("KINEGEN_OPT", "-O9 -fplugin=x.so")
    with pytest.raises(ValueError, match="KINEGEN_OPT='-O9 -fplugin=x.so': expected one of -O0, -O1, -O2, -O3, -Os"):
        script.compile_flags(fast=False)
    from codegen.cli import main
    description = tmp_path / "arm.toml"
    description.write_text('name = "arm"\n[[joint]]\ntype = "R"\na = 1\n')
    for argv in (["generate", str(description), "--out", str(tmp_path / "pkg")], ["build", "planar_2r"]):
        assert main(["--quiet", *argv]) == 2
        assert "KINEGEN_OPT must be one of -O0, -O1, -O2, -O3, -Os" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.toml"]


def test_numpy_chunks_equal_one_chunk():
    """The numpy kernels work through big batches CHUNK poses at a time."""
    k = kernels("puma560", "numpy")
    q = np.random.default_rng(6).uniform(-2, 2, (2 * k.CHUNK + 3, 6))
    whole = k.jacobian(q)
    pieces = np.concatenate([k.jacobian(q[s:s + 7]) for s in range(0, len(q), 7)])
    np.testing.assert_array_equal(whole, pieces)
    grid = q[:len(q) // 3 * 3].reshape(-1, 3, 6)
    np.testing.assert_array_equal(k.fk(grid).reshape(-1, 4, 4), k.fk(q[:len(grid) * 3]))


def test_benchmark_quick_run_writes_a_table(tmp_path):
    """`benchmarks/run.py --quick` runs (peers that are not installed say so) and writes its report."""
    out = tmp_path / "results.md"
    result = subprocess.run([sys.executable, str(REPO / "benchmarks" / "run.py"), "--quick", "--quiet",
                             "--robots", "planar_3r", "--count", "300", "--out", str(out)],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    text = out.read_text()
    assert "| planar_3r | fk |" in text and "## Inside C" in text and "## Targets" in text
    row = next(line for line in text.splitlines() if line.startswith("| planar_3r | fk |"))
    cells = [c.strip() for c in row.split("|")[3:-1]]
    assert "×" in cells[0] and ("ns" in cells[0] or "µs" in cells[0])  # kinegen C: a time and ratios
    assert math.isfinite(float(cells[2].split()[0]))  # lambdify measured


@pytest.mark.parametrize("name", ["planar_3r", "adept_three", "scorbot_er7"])
def test_cheap_derivative_simplification_gives_what_trigsimp_gives(models, name):
    """The task Jacobian skips trigsimp (the Puma's cold derivation: 13 s of 20): same expressions.

    The Puma is left out only for time (trigsimp takes 13 s there); its generated
    code is byte-identical either way, which test_codegen's freshness check holds.
    """
    import sympy as sp
    from derivations.chain import simplify_derivative, simplify_entry
    m = models[name]
    raw = m.task.jacobian(sp.Matrix(m.q))
    assert raw.applyfunc(simplify_derivative) == raw.applyfunc(simplify_entry)


def test_numpy_sine_and_cosine_from_the_half_angle_tangent_match_libm():
    """numpy kernels take sin and cos from h = tan(angle/2); near 0, pi/2, pi and far out they match libm.

    planar_2r's fk holds cos(q1 + q2) and sin(q1 + q2) as entries (0, 0) and (1, 0).
    """
    k = kernels("planar_2r", "numpy")
    rng = np.random.default_rng(8)
    angles = np.concatenate([rng.uniform(-4, 4, 2000), rng.uniform(-1e4, 1e4, 2000),
                             np.pi / 2 + rng.uniform(-1e-7, 1e-7, 200), np.pi - rng.uniform(0, 1e-7, 200),
                             -np.pi + rng.uniform(0, 1e-7, 200), rng.uniform(-1e-9, 1e-9, 200),
                             [0.0, np.pi, -np.pi, np.pi / 2, 3 * np.pi]])
    T = k.fk(np.stack([angles, np.zeros_like(angles)], axis=-1))
    cos = np.array([math.cos(a) for a in angles])
    sin = np.array([math.sin(a) for a in angles])
    assert np.abs(T[:, 0, 0] - cos).max() <= 4.5e-16
    assert np.abs(T[:, 1, 0] - sin).max() <= 4.5e-16
    assert (np.abs(T[:, 1, 0] - sin) <= 4.5e-16 * np.abs(sin)).all()  # sin is relatively accurate, even near 0


@pytest.mark.parametrize("kernel, size", [("fk", 16), ("jacobian", 36)])
def test_batches_past_the_caches_stream_the_same_numbers_aligned_or_not(kernel, size):
    """Outputs over KINEGEN_STREAM_BYTES (1 MiB) go out in streaming stores when 16-byte aligned.

    Both the streamed path (a numpy output) and the plain one (an output 8 bytes
    off alignment, through the C entry point) must give the per-pose results.
    """
    from generated.puma560._puma560_c import ffi, lib
    k = kernels("puma560", "c")
    count = 2 * (1 << 20) // (8 * size) + 5  # twice the threshold, and a partial block
    q = np.random.default_rng(9).uniform(-3, 3, (count, 6))
    streamed = getattr(k, kernel)(q)
    picks = np.random.default_rng(10).choice(count, 300, replace=False)
    single = np.stack([getattr(k, kernel)(q[i]) for i in picks])
    np.testing.assert_allclose(streamed[picks], single, rtol=0, atol=1e-14)
    buffer = np.zeros(count * size + 1)
    shifted = ffi.from_buffer("double[]", buffer) + 1  # 8 bytes past a 16-byte boundary
    assert int(ffi.cast("uintptr_t", shifted)) % 16 == 8
    getattr(lib, f"puma560_{kernel}_batch")(count, ffi.from_buffer("double[]", q), ffi.NULL, shifted)
    np.testing.assert_array_equal(buffer[1:].reshape(streamed.shape), streamed)


@pytest.mark.parametrize("name", ["puma560", "adept_three"])
def test_numpy_half_angle_stays_finite_and_exact_at_and_near_pi(models, name):
    """At q = +-pi, tan(q/2) is large but finite (1.6e16: no double is exactly pi/2), so
    h^2 (2.7e32) does not overflow and sin = 2h/(1 + h^2), cos = (1 - h^2)/(1 + h^2) are not
    inf/inf.  fk and jacobian there, one ulp away and 1e-8 away, against SymPy at 30 digits
    (the verifier's max-norm relative error), every revolute joint at once and one at a time.
    """
    from codegen.verify import reference, relative_error

    model, k = models[name], kernels(name, "numpy")
    revolute = np.array([t == "R" for t in model.joint_types])
    functions = {f.name: f for f in model.functions()}
    values = {s: float(v) for s, v in model.params.items()}
    for angle in (np.pi, -np.pi, np.nextafter(np.pi, 0.0), np.nextafter(np.pi, 4.0), np.pi - 1e-8, -np.pi + 1e-8):
        points = [np.where(revolute, angle, 0.3)] + [np.where(np.arange(len(revolute)) == j, angle, 0.3)
                                                     for j in np.flatnonzero(revolute)[:2]]
        for q in points:
            point = {**values, **{s: float(v) for s, v in zip(model.q, q)}}
            for kernel in ("fk", "jacobian"):
                got = getattr(k, kernel)(q)
                assert np.isfinite(got).all(), (kernel, q)
                (want,) = reference(functions[kernel], point)
                assert relative_error(got, want) < 1e-12, (kernel, q)


# -- one point from Python: <name>_point.c ------------------------------------------------------

def _point_arguments(name, function, rng):
    """Arguments of one point for ``function`` of robot or kernel set ``name`` (inputs of ik: poses of fk)."""
    if name in derivations.KERNEL_SETS:
        batch = derivations.load_kernel_set(name).sample_arguments(function, rng, 1)
        return [np.ascontiguousarray(np.asarray(a, dtype=float).reshape(-1)) for a in batch]
    k = kernels(name, "c")
    if function.name == "ik":
        q = rng.uniform(-1.2, 1.2, len(k.JOINTS))
        return [np.ascontiguousarray(k.task(q))]
    return [rng.uniform(-1.2, 1.2, len(a.symbols)) for a in function.arguments]


def _functions(name):
    if name in derivations.KERNEL_SETS:
        return derivations.load_kernel_set(name).functions()
    return derivations.load(name).functions()


@pytest.mark.parametrize("name", list(derivations.ROBOTS) + list(derivations.KERNEL_SETS))
def test_one_point_in_c_equals_the_batched_path_bit_for_bit(name):
    """Every kernel without requirement statuses has a one-point entry (robot_point.c.j2).

    Its result must be the batched entry's for a batch of one (the same C function,
    reached through cffi), bit for bit, in the same dtypes, shapes and types.
    """
    k = kernels(name, "c")
    rng = np.random.default_rng(12)
    covered = 0
    for function in _functions(name):
        if function.requires:
            assert not hasattr(k._point, function.name)  # statuses are checked in Python
            continue
        for _ in range(5):
            args = _point_arguments(name, function, rng)
            direct = getattr(k._point, function.name)(*args)
            assert direct is not None, (name, function.name, args)
            through = getattr(k, function.name)(*args)
            batched = getattr(k, function.name)(*[a[None] for a in args])
            direct, through, batched = (r if isinstance(r, tuple) else (r,) for r in (direct, through, batched))
            for d, t, b in zip(direct, through, batched, strict=True):
                assert type(d) is np.ndarray and d.dtype == b.dtype and d.shape == b.shape[1:]
                assert d.flags.writeable and d.flags.c_contiguous and d.base is None
                np.testing.assert_array_equal(d, b[0])
                np.testing.assert_array_equal(t, b[0])
        covered += 1
    assert covered >= 1


class _Subclass(np.ndarray):
    pass


@pytest.mark.parametrize("q", [
    [0.5] * 6,  # a list
    np.full(6, 0.5, dtype=np.float32),
    np.full(6, 0.5).astype(">f8"),  # another byte order
    np.full(12, 0.5)[::2],  # not contiguous
    np.full((1, 6), 0.5),  # a batch of one
    np.full(7, 0.5),  # the wrong size
    np.full(6, 0.5).view(_Subclass),
], ids=["list", "float32", "big-endian", "strided", "batch-of-one", "size-7", "subclass"])
def test_anything_but_one_plain_point_leaves_c_to_the_general_path(q):
    k = kernels("puma560", "c")
    assert k._point.fk(q) is None
    if np.shape(q)[-1] == 6:
        np.testing.assert_array_equal(np.reshape(k.fk(q), (4, 4)), k.fk(np.full(6, 0.5)))
    else:
        with pytest.raises(ValueError, match=r"expected q of shape \(\.\.\., 6\)"):
            k.fk(q)


def test_one_point_refusals_are_explained_by_the_general_path():
    k = kernels("puma560", "c")
    for bad in (np.nan, np.inf):
        q = np.zeros(6)
        q[4] = bad
        assert k._point.jacobian(q) is None
        with pytest.raises(ValueError, match="jacobian: q contains NaN or inf"):
            k.jacobian(q)
    x = k.task(np.zeros(6))
    x[3] = 2.0  # r11: no longer a rotation
    assert k._point.ik(x) is None
    with pytest.raises(ValueError, match="not a rigid transform"):
        k.ik(x)
    nan_pose = np.full(12, np.nan)  # ik takes NaN: no branch is valid
    Q, valid = k.ik(nan_pose)
    assert valid.dtype == bool and not valid.any()
    with pytest.raises(TypeError, match="fk takes 1 array argument"):
        k._point.fk()
    # Other parameters reach the one-point entry as a tuple of checked floats, and give the batch's numbers.
    q = np.full(6, 0.3)
    assert not np.allclose(k.fk(q, a2=0.5), k.fk(q))
    np.testing.assert_array_equal(k.fk(q, a2=0.5), k.fk(q[None], a2=0.5)[0])
    values = tuple(k.PARAMS.values())
    np.testing.assert_array_equal(k._point.fk(q, values), k.fk(q))
    for bad in (list(values), values[:-1], values[:-1] + (1,)):
        with pytest.raises(TypeError, match="parameter"):
            k._point.fk(q, bad)
    with pytest.raises(ValueError, match="parameter a2 must be finite"):
        k.fk(q, a2=float("inf"))


def test_one_point_calls_neither_leak_nor_keep_references():
    """Outputs are freed when dropped, inputs keep their reference counts (tracemalloc sees numpy's buffers)."""
    import tracemalloc

    k = kernels("puma560", "c")
    q, qd = np.full(6, 0.2), np.full(6, 0.1)
    x = k.task(q)
    before = sys.getrefcount(q), sys.getrefcount(x)
    calls = [lambda: k.fk(q), lambda: k.ik(x), lambda: k.manipulability(q), lambda: k.twist(q, qd),
             lambda: k.joint_velocity(q, np.ones(12))]
    for call in calls:
        call()
    tracemalloc.start()
    try:
        start = tracemalloc.get_traced_memory()[0]
        for _ in range(3000):
            for call in calls:
                call()
        grown = tracemalloc.get_traced_memory()[0] - start
    finally:
        tracemalloc.stop()
    assert grown < 50_000, grown  # 15,000 results of 48 to 384 bytes each, if they leaked
    assert (sys.getrefcount(q), sys.getrefcount(x)) == before
    assert sys.getrefcount(k.fk(q)) == sys.getrefcount(np.empty(4))  # a new array: no other reference


def test_the_c_wrap_is_the_numpy_wrap_bit_for_bit(tmp_path):
    """kinegen_wrap_angle (robot.c.j2, which returns an angle already in (-PI, PI] without its floor,
    and hands any other to kinegen_wrap_far)
    against the numpy runtime's wrap_angle, the formula alone: the same doubles, signed zeros
    included, around -pi, 0, pi and 3 pi, at the limits of the doubles, and at random angles."""
    program = _compiled_helper(tmp_path, r"static double kinegen_wrap_far\(double angle\)\n\{.*?\n\}\n\n"
                               r"static double kinegen_wrap_angle\(double angle\)\n\{.*?\n\}\n",
                               "kinegen_wrap_angle(in[0])", 1)
    rng = np.random.default_rng(27)
    angles = [rng.uniform(-10, 10, 20_000), np.array([0.0, -0.0, np.pi, -np.pi, 2 * np.pi, -2 * np.pi, 3 * np.pi,
                                                       -3 * np.pi, 1e300, -1e300, 5e-324, -5e-324])]
    for centre in (-3 * np.pi, -np.pi, 0.0, np.pi, 3 * np.pi):  # 1,000 doubles on either side of each
        below, above = [centre], [centre]
        for _ in range(1000):
            below.append(np.nextafter(below[-1], -np.inf))
            above.append(np.nextafter(above[-1], np.inf))
        angles.append(np.array(below + above))
    angles = np.concatenate(angles)
    run = subprocess.run([str(program)], input=angles.astype("<f8").tobytes(), capture_output=True, check=True)
    c_bits = np.array(run.stdout.split(), dtype=np.uint64)
    runtime = importlib.import_module("generated.puma560._runtime")
    numpy_bits = runtime.wrap_angle(angles).view(np.uint64)
    assert len(c_bits) == len(angles)
    np.testing.assert_array_equal(c_bits, numpy_bits)


def _compiled_helper(tmp_path, pattern, call, arity=2):
    """A program that applies a static helper of the generated PUMA C (found by ``pattern``) to the
    doubles on its stdin, ``arity`` at a time, ``call`` its expression of `in`, and writes each
    result's 64 bits."""
    source = (generate.GENERATED / "puma560" / "puma560.c").read_text()
    helper = re.search(pattern, source, re.S)[0]
    driver = tmp_path / "helper.c"
    driver.write_text("#include <math.h>\n#include <stdio.h>\n#include <string.h>\n" + helper + f"""
int main(void)
{{
    double in[{arity}], out;
    unsigned long long bits;
    while (fread(in, sizeof in, 1, stdin) == 1) {{
        out = {call};
        memcpy(&bits, &out, sizeof bits);
        printf("%llu\\n", bits);
    }}
    return 0;
}}
""")
    subprocess.run(["cc", "-std=c99", "-O2", "-fno-math-errno", "-Wall", "-Wextra", "-Werror", "-pedantic",
                    str(driver), "-lm", "-o", str(tmp_path / "helper")], check=True)
    return tmp_path / "helper"


def test_the_c_atan2_is_within_2_ulps_and_the_c_librarys_at_special_values(tmp_path):
    """kinegen_atan2 (robot.c.j2: Cephes' rational atan after an octant reduction, the C library's
    atan2 outside [2^-500, 2^500]) against mpmath's atan2 at 120 bits, in ulps of the exact angle:
    random pairs at every scale, every octant and sign, and the pairs where its reduction switches
    (|y| = |x|, and the smaller at 0.66 of the larger), its worst 1,500 of 100,000 against numpy's
    correctly rounded arctan2 and 1,500 more at random.  At zeros, infinities, NaN, subnormals and
    beyond 2^500 it is numpy's arctan2 bit for bit (signed zeros and +-pi included)."""
    import mpmath
    program = _compiled_helper(tmp_path, r"static double kinegen_atan2\(double y, double x\)\n\{.*?\n\}\n",
                               "kinegen_atan2(in[0], in[1])")
    rng = np.random.default_rng(26)
    n = 20_000
    signs = rng.choice([-1.0, 1.0], (n, 2))
    unit = rng.uniform(-1, 1, (n, 2))
    scaled = rng.normal(size=(n, 2)) * 10.0 ** rng.uniform(-100, 100, (n, 2))
    angle = rng.uniform(-np.pi, np.pi, n)
    circle = np.stack([np.sin(angle), np.cos(angle)], axis=1) * 10.0 ** rng.uniform(-5, 5, (n, 1))
    switch = np.stack([0.66 * (1 + rng.uniform(-1e-6, 1e-6, n)), np.ones(n)], axis=1)
    switch = (switch if rng.random() < 0.5 else switch[:, ::-1]) * signs
    diagonal = np.stack([1 + rng.uniform(-1e-9, 1e-9, n), np.ones(n)], axis=1) * signs
    pairs = np.concatenate([unit, scaled, circle, switch, np.concatenate([switch[:, ::-1], diagonal]) * 3.7])
    special = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, -5e-324, 1e-310, 2.0 ** -500, 2.0 ** -501,
                        2.0 ** 500, 2.0 ** 501, 1e308, -1e308, 1.0, -1.0, 0.5, -2.0])
    special = np.stack(np.meshgrid(special, special), axis=-1).reshape(-1, 2)
    inputs = np.concatenate([pairs, special])
    run = subprocess.run([str(program)], input=inputs.astype("<f8").tobytes(), capture_output=True, check=True)
    got = np.array(run.stdout.split(), dtype=np.uint64).view(np.float64)
    assert len(got) == len(inputs)
    reference = np.arctan2(inputs[:, 0], inputs[:, 1])
    np.testing.assert_array_equal(got[len(pairs):].view(np.uint64), reference[len(pairs):].view(np.uint64))
    got, reference = got[:len(pairs)], reference[:len(pairs)]
    assert np.isfinite(got).all() and (np.sign(got) == np.sign(reference)).all()
    from_numpy = np.abs(got - reference) / np.spacing(np.abs(reference))
    assert from_numpy.max() <= 3.0  # a quick bound on all 100,000; the exact check follows
    picked = np.concatenate([np.argsort(-from_numpy)[:1500], rng.choice(len(pairs), 1500, replace=False)])
    mpmath.mp.prec = 120
    worst = 0.0
    for i in picked:
        exact = mpmath.atan2(mpmath.mpf(float(pairs[i, 0])), mpmath.mpf(float(pairs[i, 1])))
        ulps = float(abs(mpmath.mpf(float(got[i])) - exact)) / np.spacing(abs(float(exact)))
        worst = max(worst, ulps)
    assert worst <= 2.0, worst
