"""The general 6R (issue #26, item 3): every real solution of the Kinova Jaco, a six-revolute arm
outside the closed-form families, by Raghavan and Roth's elimination in Manocha and Canny's
numeric form (derivations/ik/general_6r.py, codegen/backends/templates/general_6r.py.j2).

Every answer is held to the test's own forward kinematics (tests/test_zoo.py's DH product,
written from the description file), never to the package's fk; the configurations that make the
targets come from the same product.  The package is the zoo's, generated once per session.
The benchmark (benchmarks/general_6r.py) runs the same counts over 10,000 + 1,000 configurations.
"""
from __future__ import annotations

import itertools
import math
import os
import zlib
from pathlib import Path

import numpy as np
import pytest

from test_zoo import ARMS, fk, generated_package, generated_root, jacobian  # noqa: F401  (a fixture)

REACHED = 1e-9     # a valid answer's pose against the test's fk, max-norm over the 4 x 4 entries
SAME = 1e-6        # the generating configuration is among the answers: every joint within this (rad)
RANDOM, DEGENERATE = 300, 100


def wrapped(angle):
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def jaco_configurations():
    """RANDOM uniform configurations over the whole turn, then DEGENERATE with every joint at 0,
    +-pi/2 or pi (the Jaco stretched, folded, its wrist in line: mostly singular)."""
    rng = np.random.default_rng(zlib.crc32(b"general 6R"))
    q = rng.uniform(-math.pi, math.pi, (RANDOM + DEGENERATE, 6))
    q[RANDOM:] = rng.choice([0.0, math.pi / 2, -math.pi / 2, math.pi], (DEGENERATE, 6))
    return q


def counts(Q, valid, q, target):
    """wrong (a valid answer off its pose), no solution (no valid answer), missing (the generating
    configuration not among the valid answers), each a boolean per pose."""
    reached = np.abs(fk(ARMS["kinova_jaco"], np.where(valid[..., None], Q, 0.0)) - target[:, None]).max(axis=(-2, -1))
    wrong = (valid & (reached > REACHED)).any(axis=-1)
    distance = np.where(valid, np.abs(wrapped(Q - q[:, None, :])).max(axis=-1), np.inf).min(axis=-1)
    return wrong, ~valid.any(axis=-1), distance > SAME


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_every_real_solution_of_the_jaco(backend, generated_root):
    """Over RANDOM random configurations: no wrong answer, no pose without one, the generating
    configuration always among them, on average more solutions than the 5.7 the seeded numeric
    solver found.  Over DEGENERATE configurations at 0, +-pi/2, pi: no wrong answer, no pose without
    one, the generating configuration among them wherever it is regular (this file's Jacobian's
    smallest singular value above 1e-6) but at most once (the pose of q2 = q3 = pi/2, q5 = 0, whose
    pencil is singular on both cuts, with two real roots 0.05 rad apart: the benchmark missed one of
    465 such regular degenerate configurations), and at all but 5 % of the singular ones (a double
    root, or a continuum of solutions, where Newton from the nearest root may settle on another
    point: the benchmark missed 2 to 5 of 535; which ones varies from one generation to the next,
    as the order of a kernel's floating-point sums does)."""
    arm = ARMS["kinova_jaco"]
    k = generated_package("kinova_jaco", generated_root).load(backend)
    assert k.IK_METHOD == "general 6R"
    assert k.BRANCHES == tuple(f"solution_{i}" for i in range(1, 17))
    q = jaco_configurations()
    target = fk(arm, q)
    Q, valid = k.ik(target)
    assert Q.shape == (len(q), 16, 6) and valid.shape == (len(q), 16)
    assert np.isfinite(Q).all() and (np.abs(Q[valid]) <= np.pi).all()
    wrong, none, missing = counts(Q, valid, q, target)
    random = slice(0, RANDOM)
    assert (wrong.sum(), none.sum(), missing[random].sum()) == (0, 0, 0)
    assert valid[random].sum(axis=-1).mean() > 6.0
    regular = np.linalg.svd(jacobian(arm, q), compute_uv=False)[:, -1] > 1e-6
    degenerate = np.arange(len(q)) >= RANDOM
    assert missing[degenerate & regular].sum() <= 1
    assert missing[degenerate & ~regular].sum() <= 0.05 * (degenerate & ~regular).sum()
    # the answers: valid first, in increasing q1 (then q2, ...), none twice
    for i in range(len(q)):
        m = valid[i].sum()
        assert valid[i, :m].all() and not valid[i, m:].any()
        answers = Q[i, :m]
        assert all(tuple(a) <= tuple(b) for a, b in zip(answers, answers[1:]))
        gaps = np.abs(wrapped(answers[:, None, :] - answers[None, :, :])).max(axis=-1)
        assert (gaps + np.eye(m) * 9 > SAME).all()



@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_no_regular_degenerate_configuration_is_missed(backend, generated_root):
    """All 4,096 configurations with every joint at 0, +-pi/2 or pi, in both backends: no wrong
    answer, no pose without one, and the generating configuration among the answers at every
    regular one (the smallest singular value of this file's Jacobian above 1e-6: 1,792 of them).
    These poses give the determinant multiple roots (the C's fast pass must send them to its
    eigen-solve, whose QR steps must not stall: the IRB 140's case, tests/ik/test_urdf_zoo_ik.py)
    and make both loops' pencils singular at some (the numpy backend missed 4 regular ones while it
    turned such poses about two axes where the C takes four)."""
    arm = ARMS["kinova_jaco"]
    k = generated_package("kinova_jaco", generated_root).load(backend)
    q = np.array(list(itertools.product([0.0, np.pi / 2, -np.pi / 2, np.pi], repeat=6)))
    target = fk(arm, q)
    Q, valid = k.ik(target)
    wrong, none, missing = counts(Q, valid, q, target)
    regular = np.linalg.svd(jacobian(arm, q), compute_uv=False)[:, -1] > 1e-6
    assert regular.sum() > 1000
    assert (wrong.sum(), none.sum(), (missing & regular).sum()) == (0, 0, 0)


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_one_pose_unreachable_and_nan_targets(backend, generated_root):
    """One pose, as a 4 x 4 or as the 12 task numbers, gives the batch's answers; a pose 10 times as
    far as a reachable one, and a pose with a NaN, give no valid answer and no NaN."""
    arm = ARMS["kinova_jaco"]
    k = generated_package("kinova_jaco", generated_root).load(backend)
    q = jaco_configurations()[:5]
    target = fk(arm, q)
    Q, valid = k.ik(target)
    for i in range(5):
        vector = np.concatenate([target[i, :3, 3], target[i, :3, :3].ravel()])
        for pose in (target[i], vector):
            Q1, valid1 = k.ik(pose)
            assert Q1.shape == (16, 6) and valid1.shape == (16,)
            np.testing.assert_array_equal(valid1, valid[i])
            np.testing.assert_allclose(Q1[valid1], Q[i][valid[i]], rtol=0, atol=1e-12)
    far = target.copy()
    far[:, :3, 3] *= 10.0
    Q, valid = k.ik(far)
    assert not valid.any() and np.isfinite(Q).all()
    nan = target[:2].copy()
    nan[0, 0, 3], nan[1, 2, 2] = np.nan, np.inf
    Q, valid = k.ik(nan)
    assert not valid.any() and np.isfinite(Q).all()


def test_the_equations_hold_at_the_generating_configuration(generated_root):
    """The kernel ik_6r_equations (Manocha-Canny Eq. 9): at a configuration's pose, the loop's links
    E_k close the loop Rz(psi_1) E_1 ... Rz(psi_6) E_6 = I with the psi of that configuration (found
    from the layout the package states), and P(psi_3) m_45 = Q m_12 holds for them."""
    arm = ARMS["kinova_jaco"]
    package = generated_package("kinova_jaco", generated_root)
    orders, signs, shifts, offsets = package.GENERAL_6R_LAYOUT
    q = jaco_configurations()[:20]
    P, Q, E = package.ik_6r_equations(fk(arm, q)[:, :3].reshape(-1, 12)[:, [3, 7, 11, 0, 1, 2, 4, 5, 6, 8, 9, 10]])
    for loop, (order, sign) in enumerate(zip(orders, signs)):
        psi = np.stack([sign[k] * (q[:, order[k]] + offsets[order[k]] - shifts[order[k]]) for k in range(6)], -1)
        c, s = np.cos(psi), np.sin(psi)
        loop_product = np.broadcast_to(np.eye(4), (len(q), 4, 4))
        for k in range(6):
            turn = np.zeros((len(q), 4, 4))
            turn[:, 0, 0], turn[:, 0, 1], turn[:, 1, 0], turn[:, 1, 1] = c[:, k], -s[:, k], s[:, k], c[:, k]
            turn[:, 2, 2] = turn[:, 3, 3] = 1.0
            link = np.zeros((len(q), 4, 4))
            link[:, :3], link[:, 3, 3] = E[:, loop, k], 1.0
            loop_product = loop_product @ turn @ link
        assert np.abs(loop_product - np.eye(4)).max() < 1e-12
        m45 = np.stack([s[:, 3] * s[:, 4], s[:, 3] * c[:, 4], c[:, 3] * s[:, 4], c[:, 3] * c[:, 4], s[:, 3], c[:, 3],
                        s[:, 4], c[:, 4], np.ones(len(q))], -1)
        m12 = np.stack([s[:, 0] * s[:, 1], s[:, 0] * c[:, 1], c[:, 0] * s[:, 1], c[:, 0] * c[:, 1], s[:, 0], c[:, 0],
                        s[:, 1], c[:, 1]], -1)
        P3 = P[:, loop, 0] + c[:, 2, None, None] * P[:, loop, 1] + s[:, 2, None, None] * P[:, loop, 2]
        residual = np.einsum("nrj,nj->nr", P3, m45) - np.einsum("nrj,nj->nr", Q[:, loop], m12)
        assert np.abs(residual).max() < 1e-10


def _jaco_equations(generated_root, seed: bytes):
    """(the Jaco's general 6R layout, P, Q) of its package's ik_6r_equations at the poses (this file's fk)
    of 40 random configurations, seeded by ``seed``."""
    import derivations
    from derivations.ik.general_6r import equations_function
    arm = ARMS["kinova_jaco"]
    package = generated_package("kinova_jaco", generated_root)
    layout = equations_function(derivations.load(arm.path))[1]
    q = np.random.default_rng(zlib.crc32(seed)).uniform(-math.pi, math.pi, (40, 6))
    P, Q, _ = package.ik_6r_equations(fk(arm, q)[:, :3].reshape(-1, 12)[:, [3, 7, 11, 0, 1, 2, 4, 5, 6, 8, 9, 10]])
    return layout, P, Q


def test_q_splits_into_the_blocks_the_c_fast_pass_reduces_apart(generated_root):
    """derivations.ik.general_6r.q_blocks: the rows and columns of Q (Manocha-Canny Eq. 9) that meet no
    other's, whose left null space and least squares the C's fast pass (g6r_fast_reduce) takes block by
    block.  On the Jaco's loops, at 40 random configurations' poses (this file's fk), Q from the package's
    kernel is zero wherever a row of one block meets a column of another, and each block is one: its
    nonzero entries at a pose join its rows and columns (a search of this test's own over them); the fast
    loop (psi_3 = q5) splits 4 x 2 (the z components of p and l, p.p and p.l: no psi_1 in them) and 10 x 6."""
    layout, _, Q = _jaco_equations(generated_root, b"blocks of Q")
    for loop, blocks in enumerate(layout["blocks"]):
        assert sorted(r for rows, _ in blocks for r in rows) == list(range(14))
        assert sorted(c for _, columns in blocks for c in columns) == list(range(8))
        for rows, columns in blocks:
            others = [c for c in range(8) if c not in columns]
            assert (Q[:, loop][:, list(rows)][:, :, others] == 0.0).all(), (loop, rows)
            nonzero = Q[0, loop][np.ix_(rows, columns)] != 0.0
            reached, frontier = {("row", 0)}, [("row", 0)]
            while frontier:
                kind, i = frontier.pop()
                for j in range(len(columns) if kind == "row" else len(rows)):
                    step = ("column", j) if kind == "row" else ("row", j)
                    if (nonzero[i, j] if kind == "row" else nonzero[j, i]) and step not in reached:
                        reached.add(step)
                        frontier.append(step)
            assert len(reached) == len(rows) + len(columns), (loop, rows, columns)
    fast = layout["fast"]
    assert sorted((len(rows), len(columns)) for rows, columns in layout["blocks"][fast]) == [(4, 2), (10, 6)]


def test_p_nonzero_marks_the_entries_of_p_the_c_fast_pass_reads(generated_root):
    """derivations.ik.general_6r.p_nonzero: the entries of P_1, P_c, P_s (Manocha-Canny Eq. 9) that are not
    zero in the equations, the only ones the C's fast pass multiplies (g6r_fast_reduce).  On the Jaco's loops,
    at 40 random configurations' poses (this file's fk), P from the package's kernel is exactly zero wherever
    an entry is marked 0 (the C would be wrong otherwise), and the entries marked 1 are nonzero at some pose
    but for at most 12 a loop (the C then multiplies a zero: slower, not wrong): sums of the file's decimals as
    30-digit floats and sqrt(3) terms, such as -28 sqrt(3) D2 D3 / 425 + 0.11411... D2 D3, that cancel only
    in the numbers (under 1e-15 at every pose: on the fast loop 12, 4 of them exactly 0).  On the fast loop
    142 of the 378 are marked."""
    layout, P, _ = _jaco_equations(generated_root, b"nonzero of P")
    for loop, marks in enumerate(layout["p_nonzero"]):
        marked = np.array(marks, dtype=bool)
        assert marked.shape == (3, 14, 9)
        assert (P[:, loop][:, ~marked] == 0.0).all(), loop
        largest = np.abs(P[:, loop][:, marked]).max(axis=0)
        assert (largest <= 1e-15).sum() <= 12, (loop, (largest <= 1e-15).sum())
    assert sum(map(sum, (row for part in layout["p_nonzero"][layout["fast"]] for row in part))) == 142


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_the_pose_and_jacobian_kernel_is_the_tests_own_pose_and_jacobian(backend, generated_root):
    """ik_6r_pose_jacobian (the task and the Jacobian from one set of sines, for the C's Newton steps): its
    x is the pose of this file's DH product (position, then the rotation row by row) and its J this file's
    Jacobian by cross products (test_zoo.jacobian), to 1e-12, at random configurations and at every joint
    in {0, +-pi/2, pi}."""
    arm = ARMS["kinova_jaco"]
    k = generated_package("kinova_jaco", generated_root).load(backend)
    q = jaco_configurations()
    T = fk(arm, q)
    x, J = k.ik_6r_pose_jacobian(q)
    assert x.shape == (len(q), 12) and J.shape == (len(q), 6, 6)
    assert np.abs(x - np.concatenate([T[:, :3, 3], T[:, :3, :3].reshape(-1, 9)], axis=-1)).max() < 1e-12
    assert np.abs(J - jacobian(arm, q)).max() < 1e-12


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_the_pose_and_jacobian_from_sines_is_the_tests_own_pose_and_jacobian(backend, generated_root):
    """ik_6r_pose_jacobian_sc (the same from cos q and sin q given, for the C's first Newton look at a
    candidate, whose sines it has): this file's DH pose and cross-product Jacobian to 1e-12 at random and
    degenerate configurations, with q itself given as zeros: every angle of the Jaco's (joint 6 with its
    10 degree offset) is a joint and a constant, so its sines come from cs alone."""
    arm = ARMS["kinova_jaco"]
    k = generated_package("kinova_jaco", generated_root).load(backend)
    q = jaco_configurations()
    T = fk(arm, q)
    cs = np.stack([np.cos(q), np.sin(q)], axis=-1).reshape(len(q), 12)
    x, J = k.ik_6r_pose_jacobian_sc(np.zeros_like(q), cs)
    assert x.shape == (len(q), 12) and J.shape == (len(q), 6, 6)
    assert np.abs(x - np.concatenate([T[:, :3, 3], T[:, :3, :3].reshape(-1, 9)], axis=-1)).max() < 1e-12
    assert np.abs(J - jacobian(arm, q)).max() < 1e-12


def test_the_c_fast_pass_takes_the_loop_whose_solutions_lie_further_apart(generated_root):
    """The C's fast pass (general_6r.c.j2, G6R_FAST) solves on the loop whose real roots in psi_3 lie
    further apart (derivations.ik.general_6r.fast_loop), where its determinant resolves them best:
    over 60 random configurations, the median of the smallest gap between the psi_3 of two solutions
    (this file's answers, each held to this file's fk) is larger on the loop the C names, and by a
    factor of 2 at least on the Jaco (its loop psi_3 = q2 has its solutions in near pairs)."""
    import re
    arm = ARMS["kinova_jaco"]
    package = generated_package("kinova_jaco", generated_root)
    source = (Path(package.__file__).parent / "kinova_jaco.c").read_text()
    fast = int(re.search(r"#define G6R_FAST (\d+)", source).group(1))
    orders, signs, shifts, offsets = package.GENERAL_6R_LAYOUT
    q = np.random.default_rng(zlib.crc32(b"fast loop")).uniform(-math.pi, math.pi, (60, 6))
    target = fk(arm, q)
    Q, valid = package.load("numpy").ik(target)
    assert (np.abs(fk(arm, np.where(valid[..., None], Q, 0.0)) - target[:, None]).max(axis=(-2, -1))[valid] < REACHED).all()
    medians = []
    for order, sign in zip(orders, signs):
        joint = order[2]
        gaps = []
        for answers in (Q[i, valid[i]] for i in range(len(q))):
            psi = np.sort((sign[2] * (answers[:, joint] + offsets[joint] - shifts[joint])) % (2 * np.pi))
            if len(psi) > 1:
                gaps.append(np.diff(np.concatenate([psi, psi[:1] + 2 * np.pi])).min())
        medians.append(np.median(gaps))
    assert medians[fast] >= 2 * medians[1 - fast], (fast, medians)


def test_the_pencil_has_eight_spurious_eigenvalues_at_plus_minus_i(generated_root):
    """What the C's deflation rests on (general_6r.c.j2, g6r_deflate): Raghavan and Roth's determinant of
    degree 24 in x_3 holds the factor (1 + x_3^2)^4, and the 12 x 12 matrix quadratic is semisimple there:
    at every random pose and on both loops, M(i) = M_0 - M_2 + i M_1 has a null space of dimension 4
    (singular values 9 to 12 at rounding, the 8th well above), and the 24 x 24 companion matrix (numpy's
    eig, not the C's) has exactly 8 eigenvalues at +-i, 4 each, and 16 elsewhere.  That null space is
    the same at every pose, random or degenerate (the C finds it once per call from a reference pose,
    g6r_prepare): the first pose's null vectors (numpy's SVD) are null vectors of every other pose's
    M(i), to 1e-12 of its largest entry."""
    from derivations.ik.general_6r import numeric_pencil
    arm = ARMS["kinova_jaco"]
    package = generated_package("kinova_jaco", generated_root)
    q = np.vstack([jaco_configurations()[:20], jaco_configurations()[RANDOM:RANDOM + 20]])
    P, Q, _ = package.ik_6r_equations(fk(arm, q)[:, :3].reshape(-1, 12)[:, [3, 7, 11, 0, 1, 2, 4, 5, 6, 8, 9, 10]])
    first = {}
    for n in range(len(q)):
        for loop in range(P.shape[1]):
            M2, M1, M0 = numeric_pencil(P[n, loop], Q[n, loop])
            Mi = M0 - M2 + 1j * M1
            first.setdefault(loop, np.linalg.svd(Mi)[2][-4:].conj().T)
            assert np.abs(Mi @ first[loop]).max() < 1e-12 * np.abs(Mi).max()
            if n >= 20:   # the degenerate ones: the eigenvalues below are held at the random ones
                continue
            sv = np.linalg.svd(Mi, compute_uv=False)
            assert sv[8:].max() < 1e-12 * sv[0] and sv[7] > 1e-6 * sv[0], sv / sv[0]
            companion = np.zeros((24, 24))
            companion[:12, 12:] = np.eye(12)
            companion[12:] = -np.linalg.solve(M2, np.hstack([M0, M1]))
            lam = np.linalg.eigvals(companion)
            assert np.sum(np.abs(lam - 1j) < 1e-4) == 4 and np.sum(np.abs(lam + 1j) < 1e-4) == 4, lam


@pytest.mark.fuzz
@pytest.mark.skipif(os.environ.get("HYPOTHESIS_PROFILE") != "fuzz",
                    reason="`make fuzz` only: the sanitizer build of the Jaco's whole general 6R takes minutes (9.5 min of clang on 2026-11-27)")
def test_the_c_ik_entry_point_passes_a_short_fuzz_under_the_sanitizers(generated_root):
    """The general 6R's ik in C (general_6r.c.j2: the eigen-solve, the recovery of the joints and the
    Newton polish) under libFuzzer, AddressSanitizer and UndefinedBehaviorSanitizer, every report
    fatal: raw bytes as poses and parameters (NaN, inf, huge values), reachable poses as seeds, and
    the round trip (a valid answer must give its target back, with the parameters changed by up to
    half).  The harness also holds the single point to the batch and the return value to the valid
    answers it counts (codegen/fuzz.py)."""
    from codegen import fuzz
    missing = fuzz.clang_missing()
    if missing:
        pytest.skip(missing)
    package = generated_package("kinova_jaco", generated_root)
    folder = Path(package.__file__).parent
    k = package.load("numpy")
    q = jaco_configurations()[:4]
    kernels = (fuzz.Kernel("task", (fuzz.Argument("q", 6),), (fuzz.Argument("x", 12),), False, False),
               fuzz.Kernel("ik", (fuzz.Argument("x", 12),), (fuzz.Argument("Q", 96), fuzz.Argument("valid", 16, "int")),
                           False, True))
    fuzzed = fuzz.FuzzPackage(name="kinova_jaco", path=folder, params=tuple(k.PARAMS.items()), kernels=kernels,
                              n_joints=6, pose_task=True, reachable=tuple(map(tuple, k.task(q))))
    results = {r.target.entry: r for r in fuzz.fuzz([fuzzed], runs=150, seconds=None, jobs=2)}
    assert {"ik", fuzz.ROUND_TRIP} <= set(results)
    for entry in ("ik", fuzz.ROUND_TRIP):
        assert results[entry].failure is None, results[entry].failure
        assert results[entry].runs >= 150


@pytest.mark.parametrize("compiler", ["gcc", "clang"])
def test_the_c_solver_compiles_under_the_extra_warnings_in_every_layout(compiler, generated_root):
    """The Jaco's C (the general 6R's solver, general_6r.c.j2, with its kernels) under the project's strict
    flags and c_backend.EXTRA_WARNINGS (-Wconversion -Wshadow -Wdouble-promotion), in each layout the
    build knows (plain, blocked, SIMD): no warning at all."""
    import shutil
    import subprocess

    from codegen.backends.c_backend import EXTRA_WARNINGS, STRICT_FLAGS
    from codegen.build import LAYOUTS
    if shutil.which(compiler) is None:
        pytest.skip(f"{compiler} not installed")
    source = Path(generated_package("kinova_jaco", generated_root).__file__).parent / "kinova_jaco.c"
    assert "kinova_jaco_g6r_eigenvalues" in source.read_text()
    for layout, flags in LAYOUTS.items():
        run = subprocess.run([compiler, *STRICT_FLAGS, *EXTRA_WARNINGS, *flags, "-fsyntax-only", str(source)],
                             capture_output=True, text=True)
        assert run.returncode == 0 and not run.stderr, (layout, run.stderr)
