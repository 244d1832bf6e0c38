"""Point-to-point time laws and interpolated multi-axis motion, exact in SymPy.

Every law is an expression in the time symbol :data:`t` (seconds), measured from
the start of the move; its first and second derivatives are the velocity and
the acceleration (:func:`position_velocity_acceleration`).

* :func:`cubic` and :func:`quintic`: the polynomials of least degree meeting the
  given position and velocity (and acceleration) at both ends, derived here by
  solving the boundary conditions; with zero end velocities the cubic is
  Predescu and Stroe's Eq. 4.1 for theta2 of the SCORBOT.
* :func:`cycloidal`: Predescu and Stroe's Eq. 4.8 (the "sinusoid" law),
  ``q0 + A0 (omega0 t - sin(omega0 t)) / (2 pi)``; it covers ``A0`` in one period
  ``2 pi / omega0`` with zero velocity and acceleration at both ends.
* :func:`trapezoid`: the trapezoidal velocity profile of the velocity-model
  slides ("Interpolated motion"), with separate acceleration and deceleration
  times: ``L = v t_a / 2 + v t_m + v t_d / 2``.
* :func:`synchronize`: the slides' interpolated motion, where every axis starts
  and stops together and the slowest axis sets the duration.

Numbers come in as given: integers and rationals stay exact (the slides'
example gives ``t_m = 15/2`` s and ``v_y = 56/9`` cm/s), floats stay floats, and
symbols are allowed for the general laws that the generated kernels evaluate
(:func:`kernel_set`, the package ``generated/trajectory``).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Sequence

import sympy as sp

from .kernelset import KernelSet
from .model import Argument, Output, SymbolicFunction

__all__ = ["t", "TrajectoryError", "cubic", "quintic", "cycloidal", "trapezoid", "AxisMotion", "synchronize",
           "position_velocity_acceleration", "kernel_set"]

t = sp.Symbol("t", real=True)
"""The time symbol of every law (s), zero at the start of the move."""


class TrajectoryError(ValueError):
    """A move that cannot be made as asked; the message names the constraint."""


# -- input checks ----------------------------------------------------------------------------

def _real(value, what: str) -> sp.Expr:
    """``value`` as a SymPy real: a finite real number, or an expression that may be real."""
    try:
        x = sp.sympify(value, strict=True)
    except (sp.SympifyError, TypeError):
        raise TrajectoryError(f"{what} must be a real number, got {value!r}") from None
    if not isinstance(x, sp.Expr):
        raise TrajectoryError(f"{what} must be a real number, got {value!r}")
    if x.free_symbols:
        if x.is_real is False:
            raise TrajectoryError(f"{what} must be real, got {x}")
        return x
    if x.is_real is not True or x.is_finite is not True:
        raise TrajectoryError(f"{what} must be a finite real number, got {value!r}")
    return x


def _positive(value, what: str, unit: str) -> sp.Expr:
    x = _real(value, what)
    if x.is_positive is False:
        raise TrajectoryError(f"{what} must be > 0 {unit}, got {x}")
    return x


# -- polynomial laws -------------------------------------------------------------------------

@lru_cache(maxsize=None)
def _boundary_polynomial(order: int) -> tuple[sp.Expr, tuple[sp.Symbol, ...], tuple[sp.Symbol, ...], sp.Symbol]:
    """The polynomial of degree ``2 order + 1`` meeting derivatives 0..order at both ends.

    Returns ``(law, start, end, T)``: ``law`` in ``t``, ``start[k]`` and ``end[k]``
    the k-th derivative at ``t = 0`` and ``t = T``.  Derived by solving the
    ``2 (order + 1)`` linear boundary conditions for the coefficients.
    """
    T = sp.Symbol("T", positive=True)
    start = sp.symbols(f"s0:{order + 1}", real=True)
    end = sp.symbols(f"e0:{order + 1}", real=True)
    coefficients = sp.symbols(f"c0:{2 * order + 2}", real=True)
    law = sum(c * t**i for i, c in enumerate(coefficients))
    conditions = []
    for k in range(order + 1):
        derivative = sp.diff(law, t, k)
        conditions.append(sp.Eq(derivative.subs(t, 0), start[k]))
        conditions.append(sp.Eq(derivative.subs(t, T), end[k]))
    (solution,) = sp.linsolve(conditions, coefficients)
    law = sum(sp.factor(c) * t**i for i, c in enumerate(solution))
    return law, start, end, T


def _polynomial_law(order: int, start, end, duration) -> sp.Expr:
    law, s, e, T = _boundary_polynomial(order)
    values = {T: duration, **dict(zip(s, start)), **dict(zip(e, end))}
    return sp.expand(law.xreplace(values)) if not duration.free_symbols else law.xreplace(values)


def cubic(q0, qf, duration, v0=0, vf=0) -> sp.Expr:
    """The cubic from ``q0`` (velocity ``v0``) at ``t = 0`` to ``qf`` (velocity ``vf``) at ``t = duration``.

    Units are the caller's (rad or deg, m or cm; velocities per second);
    ``duration`` in seconds, > 0.  Returns a polynomial in :data:`t`.  With
    ``v0 = vf = 0`` it is ``q0 + 3 D t^2 / T^2 - 2 D t^3 / T^3``, ``D = qf - q0``:
    Predescu and Stroe's Eq. 4.1.
    """
    duration = _positive(duration, "cubic: duration", "s")
    start = (_real(q0, "cubic: q0"), _real(v0, "cubic: v0"))
    end = (_real(qf, "cubic: qf"), _real(vf, "cubic: vf"))
    return _polynomial_law(1, start, end, duration)


def quintic(q0, qf, duration, v0=0, vf=0, a0=0, af=0) -> sp.Expr:
    """The quintic meeting position, velocity and acceleration at ``t = 0`` and ``t = duration``.

    Same units as :func:`cubic`; ``a0``, ``af`` per second squared.  Returns a
    polynomial in :data:`t`.
    """
    duration = _positive(duration, "quintic: duration", "s")
    start = (_real(q0, "quintic: q0"), _real(v0, "quintic: v0"), _real(a0, "quintic: a0"))
    end = (_real(qf, "quintic: qf"), _real(vf, "quintic: vf"), _real(af, "quintic: af"))
    return _polynomial_law(2, start, end, duration)


def cycloidal(q0, amplitude, omega) -> sp.Expr:
    """Predescu and Stroe's Eq. 4.8: ``q0 + amplitude (omega t - sin(omega t)) / (2 pi)``.

    The paper prints it as ``theta_i + A0 omega0 / (2 pi) [t - sin(omega0 t) / omega0]``
    (times 180/pi for degrees), with ``theta_i = 0.235`` rad, ``A0 = 1.975`` rad,
    ``omega0 = pi/5`` 1/s.  The move lasts one period, ``2 pi / omega`` seconds,
    and starts and ends at rest with zero acceleration.  ``omega`` in rad/s, > 0.
    """
    q0 = _real(q0, "cycloidal: q0")
    amplitude = _real(amplitude, "cycloidal: amplitude")
    omega = _positive(omega, "cycloidal: omega", "rad/s")
    return q0 + amplitude * (omega * t - sp.sin(omega * t)) / (2 * sp.pi)


# -- trapezoidal velocity profile ------------------------------------------------------------

def _trapezoid_law(start, length, speed, accel_time, decel_time) -> sp.Expr:
    """The piecewise position of a trapezoidal move (no checks; symbols allowed)."""
    velocity = sp.sign(length) * speed  # the move runs toward the sign of its length
    duration = sp.Abs(length) / speed + (accel_time + decel_time) / 2
    return sp.Piecewise(
        (start, t < 0),
        (start + velocity * t**2 / (2 * accel_time), t < accel_time),
        (start + velocity * accel_time / 2 + velocity * (t - accel_time), t < duration - decel_time),
        (start + length - velocity * (duration - t)**2 / (2 * decel_time), t < duration),
        (start + length, True),
    )


def trapezoid(length, speed, accel_time, decel_time, start=0) -> sp.Piecewise:
    """Position of a trapezoidal-velocity move (velocity-model slides, "Interpolated motion").

    The axis accelerates uniformly for ``accel_time`` to the cruise ``speed``,
    cruises, and decelerates uniformly for ``decel_time`` to rest, covering
    ``length`` (negative: the move runs backwards).  The cruise time follows from
    the slides' ``L = v t_a / 2 + v t_m + v t_d / 2``.  Before ``t = 0`` the axis
    rests at ``start``, after the move at ``start + length``.

    Units: lengths in any unit u, speed in u/s (> 0), times in s (> 0).
    Raises :class:`TrajectoryError` when the move is zero, a time or the speed
    is not positive, or the acceleration and deceleration phases alone cover
    more than ``|length|`` (the cruise time would be negative).
    """
    length = _real(length, "trapezoid: length")
    speed = _positive(speed, "trapezoid: speed", "(length units)/s")
    accel_time = _positive(accel_time, "trapezoid: accel_time", "s")
    decel_time = _positive(decel_time, "trapezoid: decel_time", "s")
    start = _real(start, "trapezoid: start")
    if length.is_zero:
        raise TrajectoryError("trapezoid: a zero-length move (length = 0) has no velocity profile")
    ramps = speed * (accel_time + decel_time) / 2
    if (ramps - sp.Abs(length)).is_positive:
        raise TrajectoryError(
            f"trapezoid: the acceleration and deceleration phases cover speed (accel_time + decel_time) / 2 = "
            f"{ramps} > |length| = {sp.Abs(length)}; the cruise time would be negative (lower the speed or "
            f"the phase times)")
    return _trapezoid_law(start, length, speed, accel_time, decel_time)


@dataclass(frozen=True)
class AxisMotion:
    """One axis of a synchronised move: a trapezoidal profile and its phase durations.

    ``cruise_velocity`` carries the sign of ``length``; times in seconds.
    """

    length: sp.Expr
    cruise_velocity: sp.Expr
    accel_time: sp.Expr
    cruise_time: sp.Expr
    decel_time: sp.Expr

    @property
    def duration(self) -> sp.Expr:
        return self.accel_time + self.cruise_time + self.decel_time

    def position(self, start=0) -> sp.Piecewise:
        """The axis position as a function of :data:`t` (see :func:`trapezoid`)."""
        return trapezoid(self.length, sp.Abs(self.cruise_velocity), self.accel_time, self.decel_time, start)


def _per_axis(values, count: int, what: str) -> list:
    if isinstance(values, (str, bytes)) or not isinstance(values, Sequence):
        return [values] * count  # one value for every axis
    if len(values) != count:
        raise TrajectoryError(f"synchronize: {what} has {len(values)} entries for {count} axes")
    return list(values)


def synchronize(lengths, max_velocities, accel_times, decel_times) -> list[AxisMotion]:
    """Interpolated multi-axis motion: every axis starts and stops together.

    Each axis alone would cruise at its ``max_velocities[i]`` and take
    ``|L_i| / v_i + (t_ai + t_di) / 2`` seconds; the slowest sets the common
    duration ``T``, and every other axis is slowed to cruise at
    ``L_i / (T - (t_ai + t_di) / 2)`` with cruise time ``T - t_ai - t_di`` (the
    velocity-model slides' worked example: ``L_x = 110`` cm at 11 cm/s with
    ``t_ax = 2``, ``t_dx = 3`` s takes 12.5 s, and ``L_y = 70`` cm with
    ``t_ay = 1``, ``t_dy = 1.5`` s then cruises at 6.222 cm/s).

    ``lengths`` in any unit u per axis (signed), ``max_velocities`` in u/s (> 0),
    times in s (> 0); a single number for one of the last three applies to
    every axis.  Returns one :class:`AxisMotion` per axis.  Raises
    :class:`TrajectoryError` for a zero-length axis, a non-positive time or
    speed, or an axis whose acceleration and deceleration phases at its
    maximum velocity already cover more than its move.
    """
    if isinstance(lengths, (str, bytes)) or not isinstance(lengths, Sequence) or not lengths:
        raise TrajectoryError(f"synchronize: lengths must be a non-empty sequence of move lengths, got {lengths!r}")
    n = len(lengths)
    axes = list(zip(lengths, _per_axis(max_velocities, n, "max_velocities"),
                    _per_axis(accel_times, n, "accel_times"), _per_axis(decel_times, n, "decel_times")))
    fastest = []
    for i, (length, v_max, t_a, t_d) in enumerate(axes):
        name = f"synchronize: axis {i}"
        length = _number(length, f"{name} length")
        v_max = _number(v_max, f"{name} max velocity")
        t_a = _number(t_a, f"{name} accel time")
        t_d = _number(t_d, f"{name} decel time")
        if length == 0:
            raise TrajectoryError(f"{name}: a zero-length move (length = 0); leave a stationary axis out")
        for value, what, unit in ((v_max, "max velocity", "(length units)/s"), (t_a, "accel time", "s"),
                                  (t_d, "decel time", "s")):
            if value <= 0:
                raise TrajectoryError(f"{name}: {what} must be > 0 {unit}, got {value}")
        ramps = v_max * (t_a + t_d) / 2
        if ramps > abs(length):
            raise TrajectoryError(
                f"{name}: the acceleration and deceleration phases at the maximum velocity cover "
                f"{ramps} > |length| = {abs(length)}; the cruise time would be negative")
        fastest.append((length, t_a, t_d, abs(length) / v_max + (t_a + t_d) / 2))
    duration = max(T for *_, T in fastest)
    return [AxisMotion(length, length / (duration - (t_a + t_d) / 2), t_a, duration - t_a - t_d, t_d)
            for length, t_a, t_d, _ in fastest]


def _number(value, what: str) -> sp.Expr:
    x = _real(value, what)
    if x.free_symbols:
        raise TrajectoryError(f"{what} must be a number (synchronize compares durations), got {x}")
    return x


# -- derivatives and generated kernels -------------------------------------------------------

def position_velocity_acceleration(law: sp.Expr) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """``(q, dq/dt, d2q/dt2)`` of a law in :data:`t`."""
    velocity = sp.diff(law, t)
    return law, velocity, sp.diff(velocity, t)


def _state(law: sp.Expr) -> Output:
    return Output("state", position_velocity_acceleration(law), (3,),
                  doc="position, velocity, acceleration at each time")


def _polynomial_state(order: int, start, end, duration) -> Output:
    """A polynomial law and its derivatives in Horner form in the normalised time ``t / duration``.

    ``q = sum k_i tau^i`` with ``tau = t / T``: the ``k_i`` carry no negative
    powers of ``T``, velocity and acceleration are ``q'(tau) / T`` and
    ``q''(tau) / T^2``, and no power of ``t`` is formed (the same polynomial as
    :func:`cubic` / :func:`quintic`, evaluated in fewer, better-conditioned steps).
    """
    law, s, e, T = _boundary_polynomial(order)
    tau = sp.Symbol("tau", real=True)
    normalised = sp.expand(law.xreplace({T: duration, **dict(zip(s, start)), **dict(zip(e, end))})
                           .xreplace({t: tau * duration}))
    first = sp.diff(normalised, tau)
    rows = (sp.horner(normalised, wrt=tau), sp.horner(first, wrt=tau) / duration,
            sp.horner(sp.diff(first, tau), wrt=tau) / duration**2)
    return Output("state", tuple(r.xreplace({tau: t / duration}) for r in rows), (3,),
                  doc="position, velocity, acceleration at each time")


def kernel_set() -> KernelSet:
    """The time laws as kernels of ``t`` and their boundary values (``generated/trajectory``).

    Each kernel returns ``(state, valid)``: ``state`` (..., 3) position,
    velocity and acceleration; ``valid`` (...) False where the inputs describe
    no move (a duration, speed or phase time not positive; a zero or too-short
    trapezoid).  Time ``t`` comes as an array of shape (..., 1); the polynomial
    and cycloidal laws extrapolate outside the move, the trapezoid rests.
    """
    real = {"real": True}
    q0, qf, duration, v0, vf, a0, af = sp.symbols("q0 qf duration v0 vf a0 af", **real)
    amplitude, omega = sp.symbols("amplitude omega", **real)
    length, speed, accel_time, decel_time = sp.symbols("length speed accel_time decel_time", **real)
    time = Argument("time", (t,), "time t (s), shape (..., 1)")

    def valid(condition) -> Output:
        return Output("valid", (condition,), (), "bool", "the inputs describe a move")

    kernels = [
        SymbolicFunction(
            "cubic",
            (time, Argument("boundary", (q0, qf, duration, v0, vf),
                            "q0, qf, duration (s), v0, vf: shape (..., 5)")),
            (_polynomial_state(1, (q0, v0), (qf, vf), duration), valid(duration > 0)),
            "Cubic time law from q0 (velocity v0) at t = 0 to qf (velocity vf) at t = duration: "
            "(state (..., 3) position, velocity, acceleration; valid (...))."),
        SymbolicFunction(
            "quintic",
            (time, Argument("boundary", (q0, qf, duration, v0, vf, a0, af),
                            "q0, qf, duration (s), v0, vf, a0, af: shape (..., 7)")),
            (_polynomial_state(2, (q0, v0, a0), (qf, vf, af), duration), valid(duration > 0)),
            "Quintic time law meeting position, velocity and acceleration at t = 0 and t = duration: "
            "(state (..., 3), valid (...))."),
        SymbolicFunction(
            "cycloidal",
            (time, Argument("law", (q0, amplitude, omega), "q0, amplitude, omega (rad/s): shape (..., 3)")),
            (_state(q0 + amplitude * (omega * t - sp.sin(omega * t)) / (2 * sp.pi)), valid(omega > 0)),
            "Cycloidal law of Predescu and Stroe Eq. 4.8, q0 + amplitude (omega t - sin(omega t)) / (2 pi), "
            "one period 2 pi / omega long: (state (..., 3), valid (...))."),
        SymbolicFunction(
            "trapezoid",
            (time, Argument("profile", (length, speed, accel_time, decel_time),
                            "length, speed (> 0), accel_time (s), decel_time (s): shape (..., 4)")),
            (_state(_trapezoid_law(0, length, speed, accel_time, decel_time)),
             valid(sp.And(sp.Ne(length, 0), speed > 0, accel_time > 0, decel_time > 0,
                          speed * (accel_time + decel_time) / 2 <= sp.Abs(length)))),
            "Trapezoidal velocity profile from 0 to length (velocity-model slides): (state (..., 3), "
            "valid (...)); at rest before t = 0 and after the move."),
    ]
    domains = {
        "cubic": {"time": ((0.0, 10.0),), "boundary": ((-2.0, 2.0), (-2.0, 2.0), (1.0, 10.0), (-1.0, 1.0),
                                                        (-1.0, 1.0))},
        "quintic": {"time": ((0.0, 10.0),), "boundary": ((-2.0, 2.0), (-2.0, 2.0), (1.0, 10.0), (-1.0, 1.0),
                                                          (-1.0, 1.0), (-1.0, 1.0), (-1.0, 1.0))},
        "cycloidal": {"time": ((0.0, 10.0),), "law": ((-2.0, 2.0), (-2.0, 2.0), (0.2, 2.0))},
        "trapezoid": {"time": ((-0.2, 3.0),), "profile": ((-3.0, 3.0), (1.0, 2.0), (0.1, 1.0), (0.1, 1.0))},
    }
    return KernelSet(
        name="trajectory",
        title="Point-to-point time laws",
        source="Predescu and Stroe Eqs. 4.1 and 4.8 (cubic, cycloidal); velocity-model slides, "
               "Interpolated motion (trapezoid); the quintic by the same boundary conditions",
        kernels=kernels,
        domains=domains,
    )
