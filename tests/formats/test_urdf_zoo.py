"""Real URDF files as shipped (tests/data/urdf/zoo/, tests/urdf_zoo.py), each arm held to the
independent chain ``XmlChain`` (the XML read with ElementTree, float64) on 100 configurations
within the joint limits.

Every arm's SymPy model, cut out with its ``--base`` and ``--tip``, is checked twice, through its
own expressions (lambdified through its program: what the kernels print, and what ``kinegen
verify`` holds them to at 30 digits):

* as written (``snap=False``): the model keeps every number the file writes, so it must equal
  the XML read as written to 1e-12;
* snapped (the default): the model reports in ``notes["snapped"]`` every angle and axis it made
  exact (1.5708 -> pi/2, an axis 0 -1 6.12323e-17 -> [0, -1, 0]).  The test reads those notes
  back, checks that each quotes the file's own number and moves it by no more than the file's
  own rounding (half a unit in the last digit written, or 1e-8), and gives the snapped values to
  ``XmlChain``, which must then again equal the model to 1e-12.  This is stricter than
  bounding the difference from the written file by the snap sizes times the arm's reach (which
  a wrong but small change would pass too), and it holds the notes to being complete: a number
  changed without a note is a difference far above 1e-12.  It does not restate which numbers
  snapping should take (derivations/urdf.py's rule); only that what it took was a rounding.

The arms that did not generate before issue #25 (``GENERATED``) are generated whole, numpy and
C, by the CLI in a process of their own, and both backends are held to the XML the same way;
their C holds no integer literal past 2^53.

``pytest tests/formats/test_urdf_zoo.py -k "not generated"`` is the quick part; ``-k xarm7`` one arm.
"""
from __future__ import annotations

import fcntl
import hashlib
import importlib
import os
import re
import subprocess
import sys
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from conftest import shared_folder
from urdf_zoo import ZOO, ZOO_DIR, XmlChain, relative_error

TOLERANCE = 1e-12
SAMPLES = 100
ROOT = Path(__file__).resolve().parents[2]
SNAP_TOLERANCE = 1e-8  # float noise that snapping may remove from a number written to any precision


def test_the_files_are_the_shipped_bytes():
    """Every zoo file is listed in SOURCES.md with the sha256 of the wheel's copy (never edited)."""
    listed = dict(re.findall(r"^\| `([\w.]+\.urdf)` \|.*\| `([0-9a-f]{64})` \|$",
                             (ZOO_DIR / "SOURCES.md").read_text(), re.M))
    assert sorted(listed) == sorted(p.name for p in ZOO_DIR.glob("*.urdf"))
    for name, digest in listed.items():
        assert hashlib.sha256((ZOO_DIR / name).read_bytes()).hexdigest() == digest, name
    assert {arm.file for arm in ZOO.values()} <= set(listed)


@pytest.mark.parametrize("name", list(ZOO))
def test_the_reference_chain_has_its_joints_and_its_jacobian_is_the_derivative_of_its_fk(name):
    """The check's own check: the chain has the table's number of moving joints, and its Jacobian
    equals central differences of its fk (linear part; angular part from dR R^T)."""
    arm = ZOO[name]
    chain = XmlChain(arm.path, arm.base, arm.tip)
    assert chain.n == arm.joints and 1 <= chain.n <= 8
    h = 1e-6
    for q in chain.configurations(5, 7):
        T, J = chain.fk(q), chain.jacobian(q)
        for j in range(chain.n):
            dq = np.zeros(chain.n)
            dq[j] = h
            Tp, Tm = chain.fk(q + dq), chain.fk(q - dq)
            v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
            spin = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ T[:3, :3].T
            w = np.array([spin[2, 1], spin[0, 2], spin[1, 0]])
            assert np.allclose(np.concatenate([v, w]), J[:, j], atol=1e-7), (name, j)


# --------------------------------------------------------------------------- the models

def model_kernels(name: str, snap: bool):
    """The arm's SymPy model (``derivations.load``, cached on disk) and its fk and geometric Jacobian
    as float64 functions of q: the model's own expressions, lambdified through its program's steps
    (the same expressions the generated kernels print and ``kinegen verify`` holds them to)."""
    import derivations
    from derivations.program import needed
    arm = ZOO[name]
    model = derivations.load(arm.path, base=arm.base, tip=arm.tip, snap=snap)
    outputs = [model.fk.tolist(), model.jacobian.tolist()]

    def program(exprs):  # lambdify's cse hook: the model's steps are the common subexpressions
        entries = [e for matrix in exprs for row in matrix for e in row]
        return list(needed(model.program, entries)), exprs

    function = sp.lambdify([model.q], outputs, modules="math", cse=program)

    class Kernels:
        @staticmethod
        def fk(q):
            return np.array([np.array(function(row)[0], dtype=float) for row in q])

        @staticmethod
        def jacobian(q):
            return np.array([np.array(function(row)[1], dtype=float) for row in q])
    return model, Kernels


def assert_kernels_match(kernels, chain: XmlChain, seed: int, samples: int = SAMPLES):
    q = chain.configurations(samples, seed)
    fk, jacobian = kernels.fk(q), kernels.jacobian(q)
    assert fk.shape == (samples, 4, 4) and jacobian.shape == (samples, 6, chain.n)
    assert relative_error(fk, np.array([chain.fk(row) for row in q])) < TOLERANCE
    assert relative_error(jacobian, np.array([chain.jacobian(row) for row in q])) < TOLERANCE


@pytest.mark.parametrize("name", list(ZOO))
def test_the_model_as_written_matches_the_xml(name):
    arm = ZOO[name]
    model, kernels = model_kernels(name, False)
    assert "snapped" not in model.notes
    assert_kernels_match(kernels, XmlChain(arm.path, arm.base, arm.tip), 17)


SNAP_NOTE = re.compile(r"^(?P<joint>\S+) (?:origin rpy\[(?P<index>[012])\] (?P<angle>\S+)|axis (?P<axis>.+?))"
                       r" -> (?P<exact>.+)$")


def rounding(texts) -> float:
    """What writing a number to the digits of ``texts`` may move it by: half a unit in the last
    digit of the least precise (``1.5708``: 5e-5), or 1e-8 (float noise) if that is more."""
    return max([SNAP_TOLERANCE] + [0.5 * 10.0 ** Decimal(text).as_tuple().exponent for text in texts])


def snapped_numbers(notes: str, chain: XmlChain) -> tuple[dict, dict]:
    """``XmlChain``'s replacements (rpy, axes) from the model's note "j1 origin rpy[1] 3.141592653
    -> pi; j2 axis 0 -1 6.12323e-17 -> [0, -1, 0]; ...", after checking that each entry quotes
    the file's own number on a joint of the chain and moves it by no more than the file's rounding
    (twice that for an axis, which is normalised after rounding)."""
    written = {j.get("name"): j for j in chain.joints}
    rpy, axes = {}, {}
    for entry in filter(None, notes.split("; ")):
        match = SNAP_NOTE.match(entry)
        assert match and match["joint"] in written, f"unexpected snap note {entry!r}"
        joint = written[match["joint"]]
        if match["index"] is not None:
            k = int(match["index"])
            text = joint.find("origin").get("rpy").split()[k]
            exact = float(sp.sympify(match["exact"]))
            assert float(match["angle"]) == float(text) and abs(exact - float(text)) <= rounding([text]), entry
            rpy[match["joint"], k] = exact
        else:
            texts = joint.find("axis").get("xyz").split()
            in_file = np.array([float(v) for v in texts])
            exact = np.array([float(v) for v in sp.sympify(match["exact"])])
            quoted = [float(v) for v in re.split(r"[\s,]+", match["axis"].strip("[] "))]
            assert np.array_equal(quoted, in_file), entry
            assert np.max(np.abs(in_file / np.linalg.norm(in_file) - exact)) <= 2 * rounding(texts), entry
            axes[match["joint"]] = exact
    return rpy, axes


@pytest.mark.parametrize("name", list(ZOO))
def test_the_model_snapped_matches_the_xml_with_the_reported_snaps(name):
    arm = ZOO[name]
    model, kernels = model_kernels(name, True)
    rpy, axes = snapped_numbers(model.notes.get("snapped", ""), XmlChain(arm.path, arm.base, arm.tip))
    assert_kernels_match(kernels, XmlChain(arm.path, arm.base, arm.tip, rpy=rpy, axes=axes), 19)


# --------------------------------------------------------------------------- generated packages

# The arms that broke before issue #25 in the C, generated whole as a user would (numpy and the C,
# compiled with the strict flags, in a fresh process): the xArm 7 as written (1.5708 for pi/2,
# snapped), the SO-101 (15-digit decimals, whose exact products reached the C as integers past 64
# bits) with --no-snap, and the KR 210 (whose ik had sqrt(3519564161475607455144369219509)).  The
# iCub and PR2 arms, whose files a full URDF parser refused, are read and checked above.
GENERATED = {"xarm7": True, "so101": False, "kr210": True}
# No integer literal of the C beyond what a double holds exactly (an exact integer past 2^53).
INTEGER_LITERAL = re.compile(r"(?<![\w.])(\d+)(?![\w.])")


@pytest.fixture(scope="session")
def zoo_packages(tmp_path_factory):
    return shared_folder(tmp_path_factory, "urdf_zoo_packages")


def generated_package(name: str, root: Path):
    """The arm generated into ``root`` by the CLI in a process of its own (once per run in a
    conftest.shared_folder: under a lock, as another worker may be generating it), then imported."""
    arm = ZOO[name]
    out = root / f"zoo_{name}"
    with open(root / f"zoo_{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not out.exists():
            snap = [] if GENERATED.get(name, True) else ["--no-snap"]
            # --no-dynamics: these files carry inertials, whose eight kernels would take the xArm 7 from 19 s
            # to over a minute here; the dynamics are tested in test_dynamics.py and against Pinocchio in
            # benchmarks/dynamics.py
            result = subprocess.run([sys.executable, "-m", "codegen", "--quiet", "generate", str(arm.path), "--base",
                                     arm.base, "--tip", arm.tip, "--out", str(out), "--no-dynamics", *snap], cwd=ROOT,
                                    env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True, text=True,
                                    timeout=600)
            assert result.returncode == 0, result.stderr
    sys.path.insert(0, str(root))
    importlib.invalidate_caches()
    try:
        return importlib.import_module(out.name), out
    finally:
        sys.path.remove(str(root))


@pytest.mark.parametrize("name", list(GENERATED))
def test_generated_package_matches_the_xml_in_both_backends(name, zoo_packages):
    arm = ZOO[name]
    package, folder = generated_package(name, zoo_packages)
    chain = XmlChain(arm.path, arm.base, arm.tip)
    if GENERATED[name]:
        import derivations
        notes = derivations.load(arm.path, base=arm.base, tip=arm.tip).notes.get("snapped", "")
        rpy, axes = snapped_numbers(notes, chain)
        chain = XmlChain(arm.path, arm.base, arm.tip, rpy=rpy, axes=axes)
    for backend in ("numpy", "c"):
        assert_kernels_match(package.load(backend), chain, 23, samples=50)
    sources = list(folder.glob("*.c"))
    assert sources, "no C source"
    for path in sources:
        text = re.sub(r"/\*.*?\*/", "", path.read_text(), flags=re.S)  # comments hold dates, hashes
        big = [int(m) for m in INTEGER_LITERAL.findall(text) if int(m) > 2**53]
        assert big == [], (path.name, big[:3])
