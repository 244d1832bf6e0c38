"""The dynamics kernels (issue #30) against Pinocchio, on real arms with published inertials.

Each arm of ``ARMS`` (a file of tests/data/urdf/zoo/, whose source SOURCES.md gives, with the
``--base`` and ``--tip`` of tests/urdf_zoo.py) is generated as a user would, in a fresh process
with an empty derivation cache: ``python -m codegen generate FILE --base B --tip T --no-snap``
(the numbers as written, which is how Pinocchio reads them).  Its cold derivation is timed in a
second fresh process: the model (kinematics), then the equations of motion
(``derivations.mechanics.dynamics``), then the common subexpressions of the seven dynamics kernels.

Pinocchio's model of the same file (``buildModelFromUrdf``) is reduced to the arm's joints with
``buildReducedModel``, every other joint (fingers) locked at zero, which is how our reader folds
the links off the chain into the chain's bodies.  On ``STATES`` random states (joints within their
limits, rates in +-2 rad/s, accelerations in +-5 rad/s^2, torques from those) we compare, in the C
backend: ``inverse_dynamics`` with ``rnea``, ``mass_matrix`` with ``crba``, ``gravity`` with
``computeGeneralizedGravity``, ``coriolis`` with ``computeCoriolisMatrix``, ``coriolis_vector``
with that matrix times qd, and ``forward_dynamics`` with ``aba``.  Each error is the largest over
the states of ``max|ours - theirs| / max|theirs|`` (the max-norm relative error of the vector or
matrix); the target is 1e-10.

Times: our C kernels batched (one call on ``BATCH`` states, per state) and one call from Python
with one state; Pinocchio's Python call with one state (it has no batched call), best of 5 runs of
``timeit``.  The issue's targets for a 6- or 7-joint arm: inverse_dynamics 150 ns per state
batched and 1 us a single call; mass_matrix and forward_dynamics within twice that.

    .venv-bench/bin/python benchmarks/dynamics.py [--out benchmarks/dynamics.md] [--states 1000] [ARM ...]
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import subprocess
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from urdf_zoo import ZOO  # noqa: E402  (tests/ is not a package)

# Arms with published inertials in their URDF (tests/data/urdf/zoo/SOURCES.md gives each file's
# wheel, upstream and licence): a UR, the Panda, a 7-joint xArm, a desktop arm (the 5-joint SO-101),
# a Kinova JACO2, a Unitree Z1 and an industrial KUKA KR 210.
ARMS = ("ur3", "panda", "xarm7", "so101", "kinova_j2s6s200", "z1", "kr210")
# Arms with actuator models (docs/dynamics.md#actuator-models): a TOML over a zoo arm's URDF, whose
# rotors, gears and friction Pinocchio is given from the TOML as read here (tomllib), not by our reader.
DRIVES = {"ur3_drive": ("ur3", ROOT / "tests" / "data" / "dynamics" / "ur3_drive.toml")}
STATES = 1000
BATCH = 10000
KERNELS = ("inverse_dynamics", "mass_matrix", "gravity", "coriolis", "coriolis_vector", "forward_dynamics")
COUNTED = (*KERNELS, "static_torques", "regressor")

COLD = """
import json, sys, time
start = time.perf_counter()
import derivations
from codegen.kernels import prepare
model = derivations.load(sys.argv[1], base=sys.argv[2], tip=sys.argv[3], snap=sys.argv[4] == "True")
loaded = time.perf_counter()
dynamics = model.dynamics
derived = time.perf_counter()
ops = {}
for f in dynamics.functions:
    ops[f.name] = prepare(f, tuple(str(s) for s in model.params)).operations
done = time.perf_counter()
print(json.dumps({"model": loaded - start, "dynamics": derived - loaded, "cse": done - derived,
                  "steps": len(dynamics.program), "operations": ops}))
"""


def fresh_env(cache: str) -> dict:
    return dict(os.environ, KINEGEN_CACHE=cache, PYTHONPATH=str(ROOT))


def snap_is_exact(name: str) -> bool:
    """Whether snapping moves the arm's numbers by float noise only (a file writing pi/2 as
    1.5707963267948966): then the default, snapped model is Pinocchio's to 1e-15, and its exact
    right angles save operations.  A file writing 1.5708 (the xArm) is generated with --no-snap."""
    from derivations.formats.urdf import read_urdf
    arm = ZOO[name]
    chains = [read_urdf(arm.path, base=arm.base, tip=arm.tip, snap=snap).joints for snap in (True, False)]
    for snapped, written in zip(*chains):
        for a, b in ((snapped.origin, written.origin), (snapped.axis, written.axis), (snapped.after, written.after)):
            if a is not None and max(abs(float(x) - float(y)) for x, y in zip(a, b)) > 1e-14:
                return False
    return True


def generate(name: str, out: Path, snap: bool) -> float:
    if name in DRIVES:  # the TOML names its URDF, ends and snapping
        source = [str(DRIVES[name][1])]
    else:
        arm = ZOO[name]
        source = [str(arm.path), "--base", arm.base, "--tip", arm.tip, *([] if snap else ["--no-snap"])]
    with tempfile.TemporaryDirectory(prefix="kinegen-dynamics-cache-") as cache:
        start = time.perf_counter()
        result = subprocess.run([sys.executable, "-m", "codegen", "--quiet", "generate", *source, "--fast", "--out",
                                 str(out)], cwd=ROOT, env=fresh_env(cache), capture_output=True, text=True)
        total = time.perf_counter() - start
    if result.returncode != 0:
        raise RuntimeError(f"{name}: generate failed: {result.stderr[-2000:]}")
    return total


def cold_derivation(name: str, snap: bool) -> dict:
    arm = ZOO[name]
    with tempfile.TemporaryDirectory(prefix="kinegen-dynamics-cache-") as cache:
        result = subprocess.run([sys.executable, "-c", COLD, str(arm.path), arm.base, arm.tip, str(snap)], cwd=ROOT,
                                env=fresh_env(cache), capture_output=True, text=True, check=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


def import_package(out: Path):
    sys.path.insert(0, str(out.parent))
    importlib.invalidate_caches()
    try:
        return importlib.import_module(out.name)
    finally:
        sys.path.remove(str(out.parent))


def pinocchio_model(pin, name: str, joints):
    if name in DRIVES:
        return pinocchio_drive(pin, name, joints)
    full = pin.buildModelFromUrdf(str(ZOO[name].path))
    lock = [full.getJointId(full.names[i]) for i in range(1, full.njoints) if full.names[i] not in joints]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    order = [model.names[i] for i in range(1, model.njoints)]
    if tuple(order) != tuple(joints):
        raise RuntimeError(f"{name}: Pinocchio's joints {order} are not ours {list(joints)}")
    return model


def pinocchio_drive(pin, name: str, joints):
    """The zoo arm's model with ``armature = Ir G^2``, ``damping`` (viscous) and ``friction``
    (Coulomb) of each joint as the TOML writes them."""
    import tomllib
    arm, path = DRIVES[name]
    model = pinocchio_model(pin, arm, joints)
    data = tomllib.loads(path.read_text())
    params = data.get("params", {})
    names = list(joints)
    for key, table in data.get("actuator", {}).items():
        k = int(key) - 1 if key.isdigit() else names.index(key)
        value = lambda field, default: params.get(table.get(field), table.get(field, default))  # noqa: E731
        model.armature[k] = value("rotor_inertia", 0.0) * value("gear_ratio", 1.0) ** 2
        model.damping[k] = value("viscous", 0.0)
        model.friction[k] = value("coulomb", 0.0)
    return model


def configuration(model, q):
    """Pinocchio's configuration vector of joint angles ``q``: a continuous joint (nq = 2) is (cos, sin)."""
    parts = []
    for joint, value in zip(list(model.joints)[1:], q):
        parts += [np.cos(value), np.sin(value)] if joint.nq == 2 else [value]
    return np.array(parts)


def states(package, rng, count: int):
    low = np.array([lim[0] if lim is not None else -np.pi for lim in package.LIMITS])
    high = np.array([lim[1] if lim is not None else np.pi for lim in package.LIMITS])
    n = len(low)
    return (rng.uniform(low, high, (count, n)), rng.uniform(-2, 2, (count, n)), rng.uniform(-5, 5, (count, n)))


def relative(ours, theirs) -> float:
    return float(np.max(np.abs(ours - theirs)) / np.max(np.abs(theirs)))


def compare(pin, model, c, Q, QD, QDD) -> dict:
    """Pinocchio's rnea, crba and aba include ``model.armature`` (as ours include the actuators'
    Ia = Ir G^2), and no friction: the viscous and Coulomb friction of the joints (Pinocchio reads a
    URDF's ``<dynamics damping friction>`` into ``model.damping`` and ``model.friction``, as ours
    does) is added here, ``damping qd + friction sign(qd)``, to rnea and taken from aba's torques."""
    data = model.createData()
    worst = dict.fromkeys(KERNELS, 0.0)
    for q, qd, qdd in zip(Q, QD, QDD):
        x = configuration(model, q)
        friction = np.asarray(model.damping) * qd + np.asarray(model.friction) * np.sign(qd)
        tau = pin.rnea(model, data, x, qd, qdd).copy() + friction
        M = pin.crba(model, data, x)
        M = np.triu(M) + np.triu(M, 1).T
        g = pin.computeGeneralizedGravity(model, data, x).copy()
        C = pin.computeCoriolisMatrix(model, data, x, qd).copy()
        qdd_aba = pin.aba(model, data, x, qd, tau - friction).copy()
        pairs = {"inverse_dynamics": (c.inverse_dynamics(q, qd, qdd), tau), "mass_matrix": (c.mass_matrix(q), M),
                 "gravity": (c.gravity(q), g), "coriolis": (c.coriolis(q, qd), C),
                 "coriolis_vector": (c.coriolis_vector(q, qd), C @ qd),
                 "forward_dynamics": (c.forward_dynamics(q, qd, tau), qdd_aba)}
        for kernel, (ours, theirs) in pairs.items():
            worst[kernel] = max(worst[kernel], relative(ours, theirs))
    # the batched C on all states at once must give what the single calls gave
    batched = c.inverse_dynamics(Q, QD, QDD)
    single = np.array([c.inverse_dynamics(q, qd, qdd) for q, qd, qdd in zip(Q, QD, QDD)])
    assert np.array_equal(batched, single), "batched and single C calls differ"
    return worst


def best(statement, number: int) -> float:
    return min(timeit.repeat(statement, number=number, repeat=5)) / number


def timings(pin, model, c, rng) -> dict:
    Q, QD, QDD = states(c, rng, BATCH)
    TAU = c.inverse_dynamics(Q, QD, QDD)
    q, qd, qdd, tau = Q[0].copy(), QD[0].copy(), QDD[0].copy(), TAU[0].copy()
    x = configuration(model, q)
    data = model.createData()
    ours_batched = {
        "inverse_dynamics": best(lambda: c.inverse_dynamics(Q, QD, QDD), 5) / BATCH,
        "mass_matrix": best(lambda: c.mass_matrix(Q), 5) / BATCH,
        "forward_dynamics": best(lambda: c.forward_dynamics(Q, QD, TAU), 5) / BATCH,
    }
    ours_single = {
        "inverse_dynamics": best(lambda: c.inverse_dynamics(q, qd, qdd), 20000),
        "mass_matrix": best(lambda: c.mass_matrix(q), 20000),
        "forward_dynamics": best(lambda: c.forward_dynamics(q, qd, tau), 20000),
    }
    theirs = {
        "inverse_dynamics": best(lambda: pin.rnea(model, data, x, qd, qdd), 20000),
        "mass_matrix": best(lambda: pin.crba(model, data, x), 20000),
        "forward_dynamics": best(lambda: pin.aba(model, data, x, qd, tau), 20000),
    }
    return {"batched": ours_batched, "single": ours_single, "pinocchio": theirs}


def ns(seconds: float) -> str:
    return f"{seconds * 1e9:,.0f}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("arms", nargs="*", help=f"arm names (default: {', '.join((*ARMS, *DRIVES))})")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "dynamics.md")
    parser.add_argument("--states", type=int, default=STATES)
    parser.add_argument("--packages", type=Path, help="keep the generated packages in this folder and reuse "
                        "them when there (a second run for the timings; generate then reports the first run's time)")
    args = parser.parse_args(argv)
    try:
        import pinocchio as pin
    except ImportError:
        print("benchmarks/dynamics.py needs Pinocchio (make bench installs it into .venv-bench)", file=sys.stderr)
        return 2
    rng = np.random.default_rng(30)
    accuracy, speed, derivation = [], [], []
    with tempfile.TemporaryDirectory(prefix="kinegen-dynamics-") as scratch:
        folder = args.packages or Path(scratch)
        folder.mkdir(parents=True, exist_ok=True)
        for name in args.arms or (*ARMS, *DRIVES):
            out = folder / f"dyn_{name}"
            snap = name in DRIVES or snap_is_exact(name)
            record = folder / f"dyn_{name}.generate-seconds"  # the first run's, for a timing rerun
            if not out.exists():
                record.write_text(str(generate(name, out, snap)))
            total = float(record.read_text()) if record.exists() else float("nan")
            cold = cold_derivation(name, snap) if name not in DRIVES else None
            package = import_package(out)
            c = package.load("c")
            model = pinocchio_model(pin, name, package.JOINTS)
            Q, QD, QDD = states(package, rng, args.states)
            worst = compare(pin, model, c, Q, QD, QDD)
            times = timings(pin, model, c, rng)
            n = len(package.JOINTS)
            file = DRIVES[name][1].relative_to(ROOT) if name in DRIVES else ZOO[name].file
            numbers = "as the TOML" if name in DRIVES else "snapped" if snap else "--no-snap"
            accuracy.append(f"| {name} | `{file}` | {n} | {numbers} | "
                            + " | ".join(f"{worst[k]:.1e}" for k in KERNELS)
                            + f" | {'yes' if max(worst.values()) <= 1e-10 else 'NO'} |")
            speed.append(f"| {name} | {n} | " + " | ".join(
                f"{ns(times['batched'][k])} / {ns(times['single'][k])} / {ns(times['pinocchio'][k])}"
                for k in ("inverse_dynamics", "mass_matrix", "forward_dynamics")) + " |")
            if cold is None:
                for table in (accuracy, speed):
                    print(table[-1], flush=True)
                continue
            ops = cold["operations"]
            derivation.append(f"| {name} | {n} | {cold['model']:.1f} | {cold['dynamics']:.1f} | {cold['cse']:.1f} | "
                              f"{total:.1f} | {cold['steps']} | " + " | ".join(f"{ops[k]:,}" if k in ops else "-" for k in COUNTED)
                              + " |")
            for table in (accuracy, speed, derivation):
                print(table[-1], flush=True)
    load = os.getloadavg()
    text = f"""# Dynamics against Pinocchio {pin.__version__} ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average {load[0]:.2f})

`.venv-bench/bin/python benchmarks/dynamics.py` (part of `make bench`). Each arm is generated with
`kinegen generate FILE --base B --tip T --fast` from its file in `tests/data/urdf/zoo/` (the wheel,
upstream and licence of each in `tests/data/urdf/zoo/SOURCES.md`; base and tip as in `tests/urdf_zoo.py`).
Pinocchio's model of the same file is reduced to the same joints (`buildReducedModel`, the others locked at
zero, as our reader folds the links off the chain into the chain's bodies). numbers: `snapped` where
snapping moves the file's numbers by float noise only (pi/2 written to 16 digits: the model is Pinocchio's
to 1e-15, and the exact right angles save operations), `--no-snap` where the file rounds them (the xArm's
1.5708, which snapping would move by 4e-6).

## Accuracy: our C kernels against Pinocchio, {args.states} random states per arm

Largest over the states of max|ours - Pinocchio| / max|Pinocchio| (target: 1e-10). inverse_dynamics: `rnea`;
mass_matrix: `crba`; gravity: `computeGeneralizedGravity`; coriolis: `computeCoriolisMatrix`; coriolis_vector:
that matrix times qd; forward_dynamics: `aba` at the torques `rnea` gave. Friction (a URDF's `<dynamics damping
friction>`, which Pinocchio reads into `model.damping` and `model.friction` and its algorithms leave out: the
Panda, the xArm, the Z1) is added to `rnea` as `damping qd + friction sign(qd)` and taken from `aba`'s torques.
ur3_drive: the UR3 with a rotor, gear and friction on each joint (`tests/data/dynamics/ur3_drive.toml`),
Pinocchio given `model.armature = Ir G^2`, `damping` and `friction` from that file.

| arm | file | joints | numbers | inverse_dynamics | mass_matrix | gravity | coriolis | coriolis_vector | forward_dynamics | within 1e-10 |
|---|---|---|---|---|---|---|---|---|---|---|
""" + "\n".join(accuracy) + f"""

## Time per state (ns): ours batched / ours one call from Python / Pinocchio one call from Python

Ours batched: one call of the C backend on {BATCH:,} states, per state. One call: the C backend's Python
function on one state (NumPy arrays in and out). Pinocchio: `rnea`, `crba`, `aba` from Python on one state.
Best of 5 `timeit` runs. The issue's targets (6 or 7 joints): inverse_dynamics 150 ns batched and 1,000 ns
one call; mass_matrix and forward_dynamics within twice those.

| arm | joints | inverse_dynamics | mass_matrix | forward_dynamics |
|---|---|---|---|---|
""" + "\n".join(speed) + """

## Cold derivation (s) and the size of the kernels (operations after common subexpressions)

In a fresh process with an empty cache: the model (kinematics), the equations of motion (the Newton-Euler
program), the common subexpressions of the eight dynamics kernels; generate: the whole cold
`kinegen generate --fast` (every kernel, numpy and C text, LaTeX, the vectorised C compile), from the first run
of `--packages` when the packages were kept (a compile several times as long as the portable default's).

| arm | joints | model | dynamics | CSE of the dynamics kernels | generate | program steps | """ + " | ".join(
        COUNTED) + """ |
|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|
""" + "\n".join(derivation) + "\n"
    args.out.write_text(text)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
