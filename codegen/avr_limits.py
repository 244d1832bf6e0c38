"""``kinegen avr3000-limits``: the AVR 3000 Matlab script (Sotirov section 6) on the command line.

    kinegen avr3000-limits [--R 18.3in] [--T 0] [--rpm 4500,4500,5500] [--units both|si|in]

Prints the joint, tool and Cartesian velocities of pure T, R and Z motion at
full motor speed and the accelerations that reach them
(``derivations.robots.extras.motor_limits.axis_limits``).  Lengths take a unit suffix
(``in``, ``mm``, ``m``; metres without one), angles ``deg`` or ``rad``; a
negative value needs the ``--R=-5in`` form.
"""
from __future__ import annotations

import argparse
import math
import sys

import derivations
from derivations.robots.extras.motor_limits import SCRIPT_R, SCRIPT_RPM, axis_limits

__all__ = ["add_parser", "run"]

LENGTH_UNITS = {"in": 0.0254, "mm": 0.001, "m": 1.0}
ANGLE_UNITS = {"deg": math.pi / 180, "rad": 1.0}


def quantity(text: str, units: dict[str, float], what: str) -> float:
    """``18.3in`` -> 0.46482: a number with an optional unit suffix (none: SI)."""
    number, factor = text, 1.0
    for suffix, scale in sorted(units.items(), key=lambda item: -len(item[0])):
        if text.endswith(suffix):
            number, factor = text[:-len(suffix)], scale
            break
    try:
        value = float(number) * factor
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{what} must be a number with an optional unit ({', '.join(units)}), got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{what} must be finite, got {text!r}")
    return value


def rpm(text: str) -> tuple[float, float, float]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"--rpm takes three comma-separated speeds (M1,M2,M3), got {text!r}")
    return values


def run(args, say) -> int:
    say("evaluating the AVR 3000 model at 30 digits")
    try:
        limits = axis_limits(derivations.load("avr3000"), R=args.R, T=args.T, motor_rpm=args.rpm)
    except ValueError as exc:  # an unreachable or singular R, a bad speed
        print(f"kinegen: error: {exc}", file=sys.stderr)
        return 2
    print(limits.table(args.units), end="")
    return 0


def add_parser(sub) -> None:
    """Register ``avr3000-limits`` on the ``kinegen`` sub-command parser."""
    p = sub.add_parser("avr3000-limits", help="AVR 3000 axis limits from motor speed limits (the Matlab script)",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("--R", type=lambda t: quantity(t, LENGTH_UNITS, "--R"), default=SCRIPT_R,
                   help="radial position, metres or with a unit: 18.3in, 464.82mm (default 18.3in)")
    p.add_argument("--T", type=lambda t: quantity(t, ANGLE_UNITS, "--T"), default=0.0,
                   help="T position, radians or with a unit: 30deg (default 0)")
    p.add_argument("--rpm", type=rpm, default=SCRIPT_RPM,
                   help="motor speed limits M1,M2,M3 in rpm (default the script's 4500,4500,5500)")
    p.add_argument("--units", choices=("both", "si", "in"), default="both", help="table units (default both)")
    p.set_defaults(run=run)
