"""Kernel sets: generated packages that are not robots.

Some kernels belong to no robot: the point-to-point time laws, or the path
construction of one paper.  A :class:`KernelSet` lists them as
:class:`~derivations.model.SymbolicFunction` s, like a robot model does, so the
same code generation, C build and verification apply unchanged.  It carries the
robot-only attributes the templates read (joints, task, branches, limits) empty.

Random test points must stay where the formulas mean something (a positive
duration, a reachable path), so each kernel set says where to sample: a
(low, high) range per argument symbol and per parameter.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

from .model import SymbolicFunction

__all__ = ["KernelSet"]

Range = tuple[float, float]


@dataclass
class KernelSet:
    """A named package of kernels with their parameters (SI defaults) and sampling ranges.

    ``domains[kernel][argument]`` holds one (low, high) range per symbol of that
    argument; ``param_ranges[symbol]`` the range a perturbed parameter is drawn
    from (the default value when a parameter has none).
    """

    name: str
    title: str
    source: str
    kernels: list[SymbolicFunction]
    params: dict[sp.Symbol, float] = field(default_factory=dict)
    domains: dict[str, dict[str, tuple[Range, ...]]] = field(default_factory=dict)
    param_ranges: dict[sp.Symbol, Range] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)
    # What the robot templates read; a kernel set has no joints, task or IK branches.
    q: tuple = ()
    joint_types: tuple = ()
    task_names: tuple = ()
    ik: list = field(default_factory=list)
    limits: tuple = ()

    def __post_init__(self):
        for kernel in self.kernels:
            ranges = self.domains.get(kernel.name, {})
            for argument in kernel.arguments:
                if len(ranges.get(argument.name, ())) != len(argument.symbols):
                    raise ValueError(f"kernel set {self.name}: {kernel.name}({argument.name}) needs one "
                                     f"sampling range per symbol ({len(argument.symbols)})")

    @property
    def n(self) -> int:
        return 0

    def functions(self) -> list[SymbolicFunction]:
        return list(self.kernels)

    def sample_arguments(self, function: SymbolicFunction, rng, count: int) -> list:
        """``count`` points per argument of ``function``, each symbol within its range.

        ``rng`` is a ``numpy.random.Generator`` (the verifier's); arrays come back
        shaped (count, len(symbols)).
        """
        ranges = self.domains[function.name]
        points = []
        for argument in function.arguments:
            low = [r[0] for r in ranges[argument.name]]
            high = [r[1] for r in ranges[argument.name]]
            points.append(rng.uniform(low, high, (count, len(low))))
        return points

    def sample_parameters(self, rng) -> dict[str, float]:
        """Parameters drawn from their ranges (keyword name -> value)."""
        values = {}
        for symbol, default in self.params.items():
            low, high = self.param_ranges.get(symbol, (default, default))
            values[str(symbol)] = float(rng.uniform(low, high))
        return values
