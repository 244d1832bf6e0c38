"""From motor speed limits to axis velocity and acceleration limits (the AVR 3000 Matlab script).

Sotirov's section 6 script takes the maximum motor speeds, moves the arm along
one tool axis at a time (pure T, pure R, pure Z: the electronic gears of
section 4) and maps the motor velocities to joint, tool and Cartesian
velocities at a given radial position R; it then asks what acceleration
reaches each maximum velocity over the axis stroke, with the rule
``AccMax = 1.5 v^2 / path`` and ``TimeAcc = 1.5 v / AccMax``.

:func:`axis_limits` does the same with the derived model: every velocity is
the model's SymPy map evaluated at 30 digits (not the generated code), and
the acceleration rule is derived, not copied (:func:`ramp_acceleration`).

Where the script is ambiguous we follow the paper and say so:

* The script assigns its motor velocity vector three times (R, T, Z motion);
  as printed only the last (Z) survives, which leaves the R and T rows of its
  acceleration block at 0 and ``TimeAcc`` at 0/0.  We evaluate the three cases
  separately.
* The motor vectors are the script's: pure R is ``(GearR, 1) x`` M2 running
  backwards, pure T is both motors forwards (GearT = 1), pure Z is M3 forwards;
  each is scaled so that no motor exceeds its limit.  With the model's signs
  (Eq. 1), the script's pure-R vector retracts the arm (Rdot < 0).
* The Z motor limit is the script's 5500 rpm; sections 2.1.2 and 5 say 6000 rpm
  (``PAPER_RPM``), so pure Z motion is also evaluated at the paper's speed and
  printed beside the script's (``AxisLimits.paper_z``).  The strokes are the
  script's (T 2 pi, R from -10 in to 20 in, Z 6 in).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import sympy as sp

from ..avr3000 import COUNTS_PER_REV

__all__ = ["SCRIPT_RPM", "PAPER_RPM", "SCRIPT_STROKES", "AxisMotion", "AxisLimits", "axis_limits", "ramp_acceleration",
           "INCH"]

INCH = 0.0254  # m
SCRIPT_RPM = (4500.0, 4500.0, 5500.0)  # MaxMotorVel_T, _R, _Z of the script
# Section 2.1.2: 4500 rpm = 471.23 rad/s for M1 and M2, 6000 rpm = 628.32 rad/s for M3 (section 5: 6000 rpm).
PAPER_RPM = (4500.0, 4500.0, 6000.0)
SCRIPT_STROKES = {"T": 2 * math.pi, "R": 30 * INCH, "Z": 6 * INCH}  # |TMax - TMin|, |RMax - RMin|, |ZMax - ZMin|
SCRIPT_R = 18.3 * INCH


def ramp_acceleration() -> tuple[sp.Expr, sp.Expr]:
    """Peak acceleration and ramp time to reach speed ``v`` over half a stroke ``L``, symbolically.

    The velocity ramp is the cubic ``v(t) = v (3 s^2 - 2 s^3)``, ``s = t / t_a``
    (zero acceleration at both ends); it covers ``v t_a / 2``, so reaching ``v``
    at mid-stroke takes ``t_a = L / v``, and the peak acceleration, at
    ``s = 1/2``, is ``1.5 v / t_a = 1.5 v^2 / L``: the script's rule.
    Returns ``(peak acceleration, t_a, v, L)``: two expressions and their symbols.
    """
    v, length, t_a, t = sp.symbols("v L t_a t", positive=True)
    s = t / t_a
    velocity = v * (3 * s**2 - 2 * s**3)
    (ramp_time,) = sp.solve(sp.Eq(sp.integrate(velocity, (t, 0, t_a)), length / 2), t_a)
    acceleration = sp.diff(velocity, t)
    peak = acceleration.subs(t, sp.solve(sp.diff(acceleration, t), t)[0])
    return sp.simplify(peak.subs(t_a, ramp_time)), ramp_time, v, length


@dataclass(frozen=True)
class AxisMotion:
    """One pure-axis motion at full motor speed, SI units.

    ``motor_rpm`` and ``motor_velocity`` (counts/s) per motor; joint, tool and
    Cartesian velocities in rad/s and m/s; ``velocity`` the moving axis's speed
    (absolute), ``stroke`` its stroke, ``acceleration`` the peak acceleration
    reaching ``velocity`` at mid-stroke, ``time_to_speed`` the ramp time.
    """

    axis: str
    motor_rpm: tuple[float, float, float]
    motor_velocity: tuple[float, float, float]
    joint_velocity: tuple[float, float, float]
    tool_velocity: tuple[float, float, float]
    cartesian_velocity: tuple[float, float, float]
    velocity: float
    stroke: float
    acceleration: float
    time_to_speed: float

    @property
    def motor_shaft_velocity(self) -> tuple[float, float, float]:
        """Motor shaft speeds in rad/s, from the counts/s and the encoder counts per revolution."""
        return tuple(v / n * 2 * math.pi for v, n in zip(self.motor_velocity, COUNTS_PER_REV))


@dataclass(frozen=True)
class AxisLimits:
    T: float
    R: float
    Z: float
    motor_rpm_limits: tuple[float, float, float]
    gear_t: float
    gear_r: float
    motions: tuple[AxisMotion, ...]
    paper_z: AxisMotion | None = None  # pure Z at the paper's M3 limit, where it differs from motor_rpm's

    @property
    def columns(self) -> tuple[tuple[str, AxisMotion], ...]:
        """(header, motion) of each table column: pure T, R, Z, and Z at the paper's speed if it differs."""
        columns = tuple((f"pure {m.axis}", m) for m in self.motions)
        if self.paper_z is not None:
            columns += ((f"pure Z, {self.paper_z.motor_rpm[2]:g} rpm", self.paper_z),)
        return columns

    def motion(self, axis: str) -> AxisMotion:
        return next(m for m in self.motions if m.axis == axis)

    def table(self, units: str = "both") -> str:
        """The script's outputs as a text table: ``units`` is "si", "in" (the paper's) or "both"."""
        if units not in ("si", "in", "both"):
            raise ValueError(f"units must be 'si', 'in' or 'both', got {units!r}")
        head = (f"AVR 3000 axis limits (Sotirov section 6 script) at T = {self.T:g} rad, "
                f"R = {self.R / INCH:g} in = {self.R:g} m, Z = {self.Z / INCH:g} in\n"
                f"motor limits {', '.join(f'{r:g}' for r in self.motor_rpm_limits)} rpm; "
                f"GearT = {self.gear_t:.8g}, GearR = {self.gear_r:.8g} (thetadot1 / thetadot2)")
        if self.paper_z is not None:
            head += (f"\nlast column: M3 at {self.paper_z.motor_rpm[2]:g} rpm, the paper's limit (sections 2.1.2 "
                     f"and 5), beside the script's {self.motor_rpm_limits[2]:g} rpm")
        blocks = [head]
        for system in (("si", "in") if units == "both" else (units,)):
            blocks.append(self._block(system))
        return "\n\n".join(blocks) + "\n"

    def _block(self, system: str) -> str:
        inch = system == "in"
        length = (lambda x: x / INCH) if inch else (lambda x: x)
        lu = "in" if inch else "m"
        columns = self.columns
        motions = [m for _, m in columns]
        rows = [("quantity", "unit") + tuple(h for h, _ in columns)]

        def row(label, unit, values):
            # Exact zeros come out of the 30-digit evaluation as rounding residues (1e-16 of GearR, say).
            rows.append((label, unit) + tuple("0" if abs(v) < 1e-12 else f"{v:.6g}" for v in values))

        for i in range(3):
            row(f"motor M{i + 1}", "rpm", [m.motor_rpm[i] for m in motions])
        for i in range(3):
            row(f"motor M{i + 1}", "counts/s", [m.motor_velocity[i] for m in motions])
        for i in range(3):  # the shaft speed, as section 2.1.2 prints it (4500 rpm = 471.23 rad/s)
            row(f"motor M{i + 1}", "rad/s", [m.motor_shaft_velocity[i] for m in motions])
        for i, (name, linear) in enumerate((("q1", False), ("q2", False), ("q3", True))):
            row(f"joint {name}dot", f"{lu}/s" if linear else "rad/s",
                [length(m.joint_velocity[i]) if linear else m.joint_velocity[i] for m in motions])
        for i, (name, linear) in enumerate((("T", False), ("R", True), ("Z", True))):
            row(f"tool {name}dot", f"{lu}/s" if linear else "rad/s",
                [length(m.tool_velocity[i]) if linear else m.tool_velocity[i] for m in motions])
        for i, name in enumerate("xyz"):
            row(f"cartesian {name}dot", f"{lu}/s", [length(m.cartesian_velocity[i]) for m in motions])
        scale = [(lambda x: x) if m.axis == "T" else length for m in motions]
        rows.append(("axis speed |v|", f"rad/s or {lu}/s") + tuple(
            f"{f(m.velocity):.6g}" for f, m in zip(scale, motions)))
        rows.append(("stroke", f"rad or {lu}") + tuple(f"{f(m.stroke):.6g}" for f, m in zip(scale, motions)))
        rows.append(("acceleration 1.5 v^2/stroke", f"rad/s^2 or {lu}/s^2") + tuple(
            f"{f(m.acceleration):.6g}" for f, m in zip(scale, motions)))
        rows.append(("time to speed", "s") + tuple(f"{m.time_to_speed:.6g}" for m in motions))
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        title = "SI units" if not inch else "inches (the paper's units)"
        lines = [title]
        for j, r in enumerate(rows):
            cells = [r[0].ljust(widths[0]), r[1].ljust(widths[1])] + [c.rjust(w) for c, w in zip(r[2:], widths[2:])]
            lines.append("  ".join(cells).rstrip())
            if j == 0:
                lines.append("  ".join("-" * w for w in widths))
        return "\n".join(lines)


def _evaluate(expressions: sp.Matrix, values: dict) -> tuple[float, ...]:
    subs = {s: sp.Rational(v) for s, v in values.items()}  # exact, so exact cancellations give exactly 0
    return tuple(float(e.xreplace(subs).evalf(30)) for e in expressions)


def axis_limits(model=None, *, R: float = SCRIPT_R, T: float = 0.0, Z: float = 0.0,
                motor_rpm: tuple[float, float, float] = SCRIPT_RPM, strokes: dict | None = None,
                paper_z_rpm: float | None = PAPER_RPM[2]) -> AxisLimits:
    """The Matlab script of Sotirov section 6, for the derived AVR 3000 model.

    ``R`` (m), ``T`` (rad), ``Z`` (m): where the arm is; ``motor_rpm``: the
    speed limits of M1, M2, M3; ``strokes``: {"T": rad, "R": m, "Z": m}
    (default: the script's); ``paper_z_rpm``: M3's limit for the extra pure-Z
    column (the paper's 6000 rpm; ``None``, or equal to ``motor_rpm[2]``, for none).  Raises ``ValueError`` for an unreachable R (|R| > 2a)
    or one where the arm is fully extended (|R| = 2a, no pure R motion).
    """
    if model is None:
        import derivations
        model = derivations.load("avr3000")
    strokes = dict(SCRIPT_STROKES, **(strokes or {}))
    for name, value in (("R", R), ("T", T), ("Z", Z)):
        if not (isinstance(value, (int, float)) and math.isfinite(value)):
            raise ValueError(f"{name} must be a finite number, got {value!r}")
    if len(motor_rpm) != 3 or not all(math.isfinite(r) and r > 0 for r in motor_rpm):
        raise ValueError(f"motor_rpm must be three positive speed limits (M1, M2, M3), got {motor_rpm!r}")
    if not all(math.isfinite(strokes[k]) and strokes[k] > 0 for k in "TRZ"):
        raise ValueError(f"strokes must be positive, got {strokes!r}")
    params = {s: v for s, v in model.params.items()}
    a = next(v for s, v in params.items() if str(s) == "a")
    if abs(R) >= 2 * a:
        raise ValueError(f"R = {R:g} m ({R / INCH:g} in): expected |R| < 2a = {2 * a:g} m ({2 * a / INCH:g} in); "
                         "beyond it the arm cannot reach, at it the arm is fully extended (singular)")
    defaults = {s: sp.Rational(v) for s, v in params.items()}
    gear_t, gear_r = (float(model.constants[k].xreplace(defaults)) for k in ("GEAR_T", "GEAR_R"))
    counts_per_rev = COUNTS_PER_REV
    limit = [rpm / 60 * n for rpm, n in zip(motor_rpm, counts_per_rev)]  # counts/s

    maps = model.maps
    tool_position = dict(zip(model.spaces["tool"].position, (T, R, Z)))
    motor_position = _evaluate(maps["tool_to_motor"].values, {**tool_position, **params})
    motor = model.spaces["motor"]

    def pure(ratio: float, sign: float) -> tuple[float, float]:
        """thetadot1 = ratio thetadot2, as fast as both motor limits allow."""
        w = min(limit[1], limit[0] / abs(ratio)) if ratio else limit[1]
        return ratio * sign * w, sign * w

    vectors = [("T", (*pure(gear_t, 1.0), 0.0)), ("R", (*pure(gear_r, -1.0), 0.0)), ("Z", (0.0, 0.0, limit[2]))]
    if paper_z_rpm is not None and paper_z_rpm != motor_rpm[2]:
        vectors.append(("Z", (0.0, 0.0, paper_z_rpm / 60 * counts_per_rev[2])))
    peak, ramp_time, v_symbol, l_symbol = ramp_acceleration()
    motions = []
    for axis, motor_velocity in vectors:
        values = {**dict(zip(motor.position, motor_position)), **dict(zip(motor.velocity, motor_velocity)), **params}
        joint_velocity = _evaluate(maps["motor_to_joint_velocity"].values, values)
        tool_velocity = _evaluate(maps["motor_to_tool_velocity"].values, values)
        cartesian_velocity = _evaluate(maps["motor_to_cartesian_velocity"].values, values)
        speed = abs(tool_velocity["TRZ".index(axis)])
        at = {v_symbol: sp.Rational(speed), l_symbol: sp.Rational(strokes[axis])}
        motions.append(AxisMotion(
            axis, tuple(v / n * 60 for v, n in zip(motor_velocity, counts_per_rev)), tuple(motor_velocity),
            joint_velocity, tool_velocity, cartesian_velocity, speed, strokes[axis],
            float(peak.evalf(30, subs=at)), float(ramp_time.evalf(30, subs=at)) if speed else math.inf))
    return AxisLimits(T, R, Z, tuple(motor_rpm), gear_t, gear_r, tuple(motions[:3]),
                      motions[3] if len(motions) > 3 else None)
