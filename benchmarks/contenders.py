"""What the benchmark times: our kernels and the tools a user would pick instead.

Each contender gives, for a robot, a kernel (``fk``, ``jacobian``, ``ik``) and a
mode (``batch``: many poses in one call where the tool allows it, a Python loop
where it does not; ``single``: one pose per call), either a :class:`Run` (a
zero-argument callable and the number of poses one call handles) or a
:class:`Missing` saying why there is no figure.  All of them work from the same
joint values, poses and task coordinates (:class:`Workload`), and the same arm:
the peers' models are built from our description files, and
:func:`agreement` checks that they compute what we compute.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np
import sympy as sp

import derivations
import generated

KERNELS = ("fk", "jacobian", "ik")


@dataclass(frozen=True)
class Run:
    call: Callable[[], object]
    items: int  # poses handled by one call
    note: str = ""  # e.g. "Python loop over 2000 poses"


@dataclass(frozen=True)
class Missing:
    reason: str


@dataclass
class Workload:
    """The inputs every contender works from, for one robot."""

    robot: str
    q: np.ndarray  # (N, n) joint values within the limits
    poses: np.ndarray  # (N, 4, 4) fk(q)
    task: np.ndarray  # (N, m) task(q), the input of our ik
    loop: int  # poses a Python loop of a slow peer runs over
    slow_loop: int  # poses for numerical IK (milliseconds each)


def workload(robot: str, count: int, loop: int, slow_loop: int, seed: int = 1) -> Workload:
    module = generated.load(robot)
    rng = np.random.default_rng(seed)
    columns = []
    for kind, lim in zip(module.JOINT_TYPES, module.LIMITS):
        low, high = lim if lim is not None else ((-math.pi, math.pi) if kind == "R" else (0.0, 0.3))
        columns.append(rng.uniform(low, high, count))
    q = np.ascontiguousarray(np.stack(columns, axis=-1))
    return Workload(robot, q, module.fk(q), np.ascontiguousarray(module.task(q)), min(loop, count),
                    min(slow_loop, count))


# -- kinegen ----------------------------------------------------------------------------------

class Kinegen:
    """Our generated kernels, in one backend."""

    def __init__(self, backend: str):
        self.backend = backend
        self.name = f"kinegen {'C' if backend == 'c' else 'numpy'}"

    def make(self, work: Workload, kernel: str, mode: str):
        module = generated.load(work.robot, self.backend)
        if kernel == "ik" and not hasattr(module, "ik"):
            return Missing("n/a (no ik yet)")
        function = getattr(module, kernel)
        data = work.task if kernel == "ik" else work.q
        if mode == "batch":
            return Run(lambda: function(data), len(data))
        one = data[0].copy()
        return Run(lambda: function(one), 1)


# -- SymPy lambdify ---------------------------------------------------------------------------

class Lambdify:
    """``sympy.lambdify(..., cse=True)`` of our SymPy expressions: what every SymPy user has.

    Batched, the columns of the inputs go in as numpy arrays and the entries come
    back one array (or constant) each, assembled into (N, ...) the way a careful
    user would: ``numpy.array(Matrix)`` is ragged when some entries are constant.
    """

    name = "lambdify(cse=True)"

    def __init__(self):
        self._functions = {}

    def _expressions(self, model, kernel):
        if kernel == "fk":
            return list(model.q), list(model.fk), (4, 4)
        if kernel == "jacobian":
            return list(model.q), list(model.jacobian), tuple(model.jacobian.shape)
        solutions = [e for branch in model.ik for e in branch.solution]
        return list(model.task_symbols), solutions, (len(model.ik), model.n)

    def make(self, work: Workload, kernel: str, mode: str):
        model = derivations.load(work.robot)
        if kernel == "ik" and not model.ik:
            return Missing("n/a (no ik yet)")
        key = (work.robot, kernel)
        if key not in self._functions:
            inputs, entries, shape = self._expressions(model, kernel)
            function = sp.lambdify(inputs + list(model.params), entries, "numpy", cse=True)
            self._functions[key] = (function, shape)
        function, shape = self._functions[key]
        params = [float(v) for v in model.params.values()]
        data = work.task if kernel == "ik" else work.q
        size = math.prod(shape)
        if mode == "batch":
            columns = list(np.ascontiguousarray(data.T))

            def batch():
                values = function(*columns, *params)
                out = np.empty((len(data), size))
                for k, v in enumerate(values):
                    out[:, k] = v
                return out.reshape((len(data),) + shape)
            return Run(batch, len(data))
        one = [float(v) for v in data[0]]
        return Run(lambda: np.array(function(*one, *params), dtype=float).reshape(shape), 1)


# -- Robotics Toolbox for Python --------------------------------------------------------------

def _dh_values(model):
    """Per joint (type, a, alpha, d, theta, offset) as floats, parameters at their defaults."""
    subs = {s: v for s, v in model.params.items()}
    rows = []
    for j in model.chain.joints:
        rows.append((j.type, *(float(sp.sympify(x).subs(subs)) for x in (j.a, j.alpha, j.d, j.theta, j.offset))))
    return rows


def _tool(model) -> np.ndarray:
    subs = {s: v for s, v in model.params.items()}
    return np.array(model.chain.tool.subs(subs).evalf(), dtype=float)


class RoboticsToolbox:
    """Robotics Toolbox for Python: ``fkine``, ``jacob0``; ``ikine_a`` (Puma 560), else ``ikine_LM``."""

    name = "RTB"

    def __init__(self):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                import roboticstoolbox as rtb
                from spatialmath import SE3
        except ImportError as exc:
            self.missing = f"not installed ({exc.name})"
            return
        self.missing = None
        self.rtb, self.SE3 = rtb, SE3
        self.version = rtb.__version__
        self._robots = {}

    def robot(self, name):
        if name not in self._robots:
            model = derivations.load(name)
            if model.chain is None or model.chain.convention != "standard":
                raise ValueError(f"{name}: not a standard DH chain")
            rtb = self.rtb
            links = []
            for kind, a, alpha, d, theta, offset in _dh_values(model):
                if kind == "R":
                    links.append(rtb.RevoluteDH(a=a, alpha=alpha, d=d, offset=offset))
                else:
                    links.append(rtb.PrismaticDH(a=a, alpha=alpha, theta=theta, offset=offset))
            if name == "puma560":  # the Toolbox's own class, which has the analytic ikine_a
                robot = rtb.models.DH.Puma560()
                for link, ours in zip(robot.links, links):
                    link.a, link.alpha, link.d, link.offset = ours.a, ours.alpha, ours.d, ours.offset
            else:
                robot = rtb.DHRobot(links, name=name)
            for link, lim in zip(robot.links, generated.load(name).LIMITS):
                if lim is not None:  # ikine_LM needs the limits of a prismatic joint
                    link.qlim = lim
            robot.tool = self.SE3(_tool(model), check=False)
            self._robots[name] = (robot, model)
        return self._robots[name]

    def _mask(self, model):
        """ikine_LM's mask of the task coordinates our ik solves for."""
        task = set(model.task_names)
        if "r11" in task:
            return None
        return [1 if c in task else 0 for c in ("x", "y", "z")] + [0, 0, 1 if "phi" in task else 0]

    def make(self, work: Workload, kernel: str, mode: str):
        if self.missing:
            return Missing(self.missing)
        robot, model = self.robot(work.robot)
        SE3 = self.SE3
        if kernel == "fk":
            if mode == "batch":  # fkine takes a trajectory of joint values
                return Run(lambda: robot.fkine(work.q), len(work.q))
            one = work.q[0].copy()
            return Run(lambda: robot.fkine(one), 1)
        if kernel == "jacobian":
            if mode == "batch":
                loop = work.q[:work.loop]
                return Run(lambda: [robot.jacob0(q) for q in loop], len(loop), f"Python loop over {len(loop)} poses")
            one = work.q[0].copy()
            return Run(lambda: robot.jacob0(one), 1)
        if work.robot == "puma560":
            solve = robot.ikine_a
            count = work.loop
        else:
            mask = self._mask(model)
            q0 = np.zeros(model.n)

            def solve(pose):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    return robot.ikine_LM(pose, q0=q0, mask=mask)
            count = work.slow_loop
        poses = [SE3(p, check=False) for p in work.poses[:count]]
        if mode == "batch":
            return Run(lambda: [solve(p) for p in poses], len(poses), f"Python loop over {len(poses)} poses")
        return Run(lambda: solve(poses[0]), 1)


class RoboticsToolboxAnalytic:
    """The Toolbox's SymPy-derived closed form (``analytic_ik``, new in 1.5): all solutions of a pose."""

    name = "RTB analytic_ik"

    def __init__(self, toolbox: RoboticsToolbox):
        self.toolbox = toolbox
        self._solvers = {}

    def solver(self, robot_name):
        if robot_name not in self._solvers:
            robot, _ = self.toolbox.robot(robot_name)
            if not hasattr(robot, "analytic_ik"):
                raise ValueError("analytic_ik needs Robotics Toolbox 1.5 or newer")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                self._solvers[robot_name] = robot.analytic_ik()
        return self._solvers[robot_name]

    def make(self, work: Workload, kernel: str, mode: str):
        if self.toolbox.missing:
            return Missing(self.toolbox.missing)
        if kernel != "ik":
            return Missing("")
        if work.robot != "puma560":
            return Missing("n/a (6R arms only)")
        try:
            solver = self.solver(work.robot)
        except (ValueError, ImportError, NotImplementedError) as exc:
            return Missing(f"n/a ({exc})")
        poses = list(work.poses[:work.loop])
        if mode == "batch":
            return Run(lambda: [solver.solve(p, joint_limits=False) for p in poses], len(poses),
                       f"Python loop over {len(poses)} poses")
        return Run(lambda: solver.solve(poses[0], joint_limits=False), 1)


# -- Pinocchio --------------------------------------------------------------------------------

class Pinocchio:
    """Pinocchio (``pin`` on PyPI): ``forwardKinematics`` and ``computeJointJacobians``.

    The model is built joint by joint from the DH table: a revolute joint turns
    about z of the previous DH frame (``JointModelRZ``), a prismatic one slides
    along it (``JointModelPZ``), and the constant part of each DH transform is the
    placement of the next joint; the last one, with the tool transform, is an
    operational frame.  The figures are the computation alone, the results left in
    Pinocchio's data, as a Pinocchio user would time it.
    """

    name = "Pinocchio"

    def __init__(self, with_result: bool = False):
        """``with_result``: also read the result out as a numpy array (what our kernels return)."""
        self.with_result = with_result
        if with_result:
            self.name = "Pinocchio, result as numpy"
        try:
            import pinocchio as pin
        except ImportError as exc:
            self.missing = f"not installed ({exc.name})"
            return
        self.missing = None
        self.pin = pin
        self.version = pin.__version__
        self._models = {}

    def model(self, name):
        if name not in self._models:
            pin = self.pin
            model = derivations.load(name)
            if model.chain is None or model.chain.convention != "standard":
                raise ValueError(f"{name}: not a standard DH chain")

            def rz(t):
                return pin.SE3(pin.utils.rotate("z", t), np.zeros(3))

            def rx(t):
                return pin.SE3(pin.utils.rotate("x", t), np.zeros(3))

            def tr(x, y, z):
                return pin.SE3(np.eye(3), np.array([x, y, z]))

            robot = pin.Model()
            parent, tail = 0, pin.SE3.Identity()
            for i, (kind, a, alpha, d, theta, offset) in enumerate(_dh_values(model)):
                if kind == "R":
                    placement, joint = tail * rz(offset), pin.JointModelRZ()
                    tail = tr(0, 0, d) * tr(a, 0, 0) * rx(alpha)
                else:
                    placement, joint = tail * rz(theta) * tr(0, 0, offset), pin.JointModelPZ()
                    tail = tr(a, 0, 0) * rx(alpha)
                parent = robot.addJoint(parent, joint, placement, f"joint{i + 1}")
            tool = pin.SE3(_tool(model))
            frame = robot.addFrame(pin.Frame("tool", parent, tail * tool, pin.FrameType.OP_FRAME))
            identity = np.allclose((tail * tool).homogeneous, np.eye(4), atol=0)
            self._models[name] = (robot, robot.createData(), parent, frame, identity)
        return self._models[name]

    def fk(self, name):
        """forwardKinematics, plus the tool frame's placement where it differs from the last joint's."""
        pin = self.pin
        robot, data, joint, frame, identity = self.model(name)
        if identity:
            return lambda q: pin.forwardKinematics(robot, data, q)

        def fk(q):
            pin.forwardKinematics(robot, data, q)
            pin.updateFramePlacement(robot, data, frame)
        return fk

    def pose(self, name):
        """The tool pose as a 4x4 numpy array (after ``fk``)."""
        robot, data, joint, frame, identity = self.model(name)
        if identity:
            return lambda: data.oMi[joint].homogeneous
        return lambda: data.oMf[frame].homogeneous

    def jacobian(self, name, with_result=True):
        """computeJointJacobians; with_result: and the tool point's [v; w] Jacobian as numpy."""
        pin = self.pin
        robot, data, joint, frame, identity = self.model(name)
        if not with_result:
            return lambda q: pin.computeJointJacobians(robot, data, q)

        def jacobian(q):
            pin.computeJointJacobians(robot, data, q)
            return pin.getFrameJacobian(robot, data, frame, pin.LOCAL_WORLD_ALIGNED)
        return jacobian

    def fk_with_result(self, name):
        fk, pose = self.fk(name), self.pose(name)

        def fk_pose(q):
            fk(q)
            return pose()
        return fk_pose

    def make(self, work: Workload, kernel: str, mode: str):
        if self.missing:
            return Missing(self.missing)
        if kernel == "ik":
            return Missing("n/a (no IK)")
        if kernel == "fk":
            function = self.fk_with_result(work.robot) if self.with_result else self.fk(work.robot)
        else:
            function = self.jacobian(work.robot, self.with_result)
        if mode == "batch":
            loop = list(work.q[:work.loop])
            return Run(lambda: [function(q) for q in loop], len(loop), f"Python loop over {len(loop)} poses")
        one = work.q[0].copy()
        return Run(lambda: function(one), 1)


def agreement(contenders, work: Workload, points: int = 3) -> dict[str, float]:
    """Largest |difference| from our C fk and Jacobian, per peer, at a few poses: the same arm?"""
    ours = generated.load(work.robot, "c")
    q = work.q[:points]
    T, J = ours.fk(q), ours.jacobian(q)
    result = {}
    for c in contenders:
        if isinstance(c, Lambdify):
            fk = c.make(Workload(work.robot, q, T, work.task[:points], points, points), "fk", "batch")
            jac = c.make(Workload(work.robot, q, T, work.task[:points], points, points), "jacobian", "batch")
            result[c.name] = max(np.abs(fk.call() - T).max(), np.abs(jac.call() - J).max())
        elif isinstance(c, RoboticsToolbox) and not c.missing:
            robot, _ = c.robot(work.robot)
            err = max(max(np.abs(robot.fkine(qi).A - Ti).max() for qi, Ti in zip(q, T)),
                      max(np.abs(robot.jacob0(qi) - Ji).max() for qi, Ji in zip(q, J)))
            result[c.name] = err
        elif isinstance(c, Pinocchio) and not c.missing and not c.with_result:
            fk, pose, jac = c.fk(work.robot), c.pose(work.robot), c.jacobian(work.robot)
            errs = []
            for qi, Ti, Ji in zip(q, T, J):
                fk(qi)
                errs.append(np.abs(pose() - Ti).max())
                errs.append(np.abs(jac(qi) - Ji).max())
            result[c.name] = max(errs)
    return result
