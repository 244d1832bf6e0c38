"""Trajectory plots as PNG files: ``python -m codegen.plots [--out DIR]`` (``make plots``).

Every curve is sampled with the generated numpy kernels (``generated.trajectory``,
``generated.scorbot_path``), the laws' parameters coming from ``derivations``:

* ``scorbot_theta2.png``: theta2(t) by the cubic Eq. 4.1 and the cycloidal Eq. 4.8
  (Predescu and Stroe Figs. 6 and 9), and theta2 of the Cartesian straight line
* ``scorbot_p5_cubic.png``, ``scorbot_p5_cycloidal.png``: velocity and acceleration
  of the tool point P5 for each theta2 law (Figs. 8 and 10)
* ``scorbot_line_joints.png``: joint angles, rates and accelerations when P5 follows
  MN with a cubic law along the line
* ``interpolated_motion.png``: the velocity-model slides' synchronised trapezoids
* ``time_laws.png``: the four point-to-point laws side by side on a unit move

Needs matplotlib (the ``plots`` extra: ``pip install -e '.[plots]'``); the Agg
backend, so no display is used.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import sympy as sp

import derivations
from derivations import scorbot_path, trajectory

__all__ = ["FIGURES", "main", "write_all"]

SAMPLES = 501


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise SystemExit("codegen.plots needs matplotlib: run `make plots` (it installs the 'plots' extra "
                         "into .venv) or `pip install -e '.[plots]'`") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _theta2_laws(model):
    """(label, theta2 state (SAMPLES, 3) in rad) of Eq. 4.1 and Eq. 4.8, and the sample times."""
    from generated import trajectory as laws
    times = np.linspace(0.0, float(scorbot_path.DURATION), SAMPLES)[:, None]
    cubic = scorbot_path.theta2_cubic(model)
    start, end = float(cubic.subs(trajectory.t, 0)), float(cubic.subs(trajectory.t, scorbot_path.DURATION))
    cubic_state, _ = laws.cubic(times, [start, end, float(scorbot_path.DURATION), 0.0, 0.0])
    cycloidal_state, _ = laws.cycloidal(times, [float(v) for v in scorbot_path.CYCLOIDAL_PARAMETERS])
    return times[:, 0], [("cubic, Eq. 4.1", cubic_state), ("cycloidal, Eq. 4.8", cycloidal_state)]


def _line_joints(times):
    from generated import scorbot_path as path
    from generated import trajectory as laws
    s_state, _ = laws.cubic(times[:, None], [0.0, 1.0, float(scorbot_path.DURATION), 0.0, 0.0])
    q, valid = path.joints_along_line(s_state)
    if not valid.all():
        raise RuntimeError("the straight line MN left the workspace: check the SCORBOT parameters")
    return q


def theta2_figure(plt, model):
    times, laws = _theta2_laws(model)
    figure, axes = plt.subplots(figsize=(6.4, 4.0))
    for label, state in laws:
        axes.plot(times, np.degrees(state[:, 0]), label=label)
    axes.plot(times, np.degrees(_line_joints(times)[:, 0, 1]), "--", label="straight line MN, cubic s(t)")
    axes.set(xlabel="time t [s]", ylabel=r"$\theta_2$ [deg]",
             title=r"SCORBOT ER-VII: $\theta_2(t)$ from M to N (Predescu and Stroe Figs. 6, 9)")
    axes.grid(True, alpha=0.3)
    axes.legend()
    return figure


def tool_point_figure(plt, model, which: int):
    from generated import scorbot_path as path
    times, laws = _theta2_laws(model)
    label, state = laws[which]
    p, valid = path.tool_point_from_theta2(state)
    if not valid.all():
        raise RuntimeError("the elbow circle missed the line MN: check the SCORBOT parameters")
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(6.4, 5.6), sharex=True)
    for axes, row, name, unit in ((top, 1, "velocity", "m/s"), (bottom, 2, "acceleration", "m/s$^2$")):
        axes.plot(times, p[:, row, 0], label="x")
        axes.plot(times, p[:, row, 1], label="z")
        axes.plot(times, np.hypot(p[:, row, 0], p[:, row, 1]), "k", label="magnitude")
        axes.set(ylabel=f"P5 {name} [{unit}]")
        axes.grid(True, alpha=0.3)
        axes.legend(loc="best", fontsize="small")
    bottom.set(xlabel="time t [s]")
    figure_number = (8, 10)[which]
    top.set_title(rf"Tool point P5 on MN, $\theta_2$ {label} (paper's Fig. {figure_number})", fontsize="medium")
    figure.tight_layout()
    return figure


def line_joints_figure(plt, model):
    times = np.linspace(0.0, float(scorbot_path.DURATION), SAMPLES)
    q = np.degrees(_line_joints(times))
    figure, axes = plt.subplots(3, 1, figsize=(6.4, 7.2), sharex=True)
    rows = (("angle", "deg"), ("rate", "deg/s"), ("acceleration", "deg/s$^2$"))
    for row, (axis, (name, unit)) in enumerate(zip(axes, rows)):
        for joint in (1, 2, 3):
            axis.plot(times, q[:, row, joint], label=rf"$\theta_{joint + 1}$")
        axis.set(ylabel=f"joint {name} [{unit}]")
        axis.grid(True, alpha=0.3)
        axis.legend(loc="best", fontsize="small")
    axes[0].set_title("SCORBOT ER-VII: P5 on the straight line MN, cubic s(t), 10 s")
    axes[-1].set(xlabel="time t [s]")
    figure.tight_layout()
    return figure


def interpolated_motion_figure(plt, model=None):
    from generated import trajectory as laws
    # The slides' numerical example: X 110 cm at 11 cm/s (2 s, 3 s ramps), Y 70 cm (1 s, 1.5 s ramps).
    axes_motion = trajectory.synchronize([110, 70], 11, [2, 1], [3, sp.Rational(3, 2)])
    duration = float(axes_motion[0].duration)
    times = np.linspace(-0.5, duration + 0.5, SAMPLES)[:, None]
    figure, axes = plt.subplots(figsize=(6.4, 3.8))
    for name, motion in zip("XY", axes_motion):
        profile = [float(motion.length), float(abs(motion.cruise_velocity)), float(motion.accel_time),
                   float(motion.decel_time)]
        state, _ = laws.trapezoid(times, profile)
        axes.plot(times[:, 0], state[:, 1],
                  label=f"{name}: L = {float(motion.length):g} cm, v = {float(motion.cruise_velocity):.3f} cm/s")
    axes.set(xlabel="time t [s]", ylabel="axis velocity [cm/s]",
             title=f"Interpolated motion: both axes finish at {duration:g} s (velocity-model slides)")
    axes.grid(True, alpha=0.3)
    axes.legend()
    return figure


def time_laws_figure(plt, model=None):
    from generated import trajectory as laws
    times = np.linspace(0.0, 1.0, SAMPLES)[:, None]
    curves = [
        ("cubic", laws.cubic(times, [0, 1, 1, 0, 0])[0]),
        ("quintic", laws.quintic(times, [0, 1, 1, 0, 0, 0, 0])[0]),
        ("cycloidal", laws.cycloidal(times, [0, 1, 2 * math.pi])[0]),
        ("trapezoid (0.25 s ramps)", laws.trapezoid(times, [1, 1 / 0.75, 0.25, 0.25])[0]),
    ]
    figure, axes = plt.subplots(3, 1, figsize=(6.4, 7.2), sharex=True)
    for row, (axis, unit) in enumerate(zip(axes, ("position [units]", "velocity [units/s]",
                                                  "acceleration [units/s$^2$]"))):
        for label, state in curves:
            axis.plot(times[:, 0], state[:, row], label=label)
        axis.set(ylabel=unit)
        axis.grid(True, alpha=0.3)
    axes[0].legend(fontsize="small")
    axes[0].set_title("Point-to-point laws: a unit move in 1 s")
    axes[-1].set(xlabel="time t [s]")
    figure.tight_layout()
    return figure


FIGURES = {
    "scorbot_theta2": theta2_figure,
    "scorbot_p5_cubic": lambda plt, model: tool_point_figure(plt, model, 0),
    "scorbot_p5_cycloidal": lambda plt, model: tool_point_figure(plt, model, 1),
    "scorbot_line_joints": line_joints_figure,
    "interpolated_motion": interpolated_motion_figure,
    "time_laws": time_laws_figure,
}


def write_all(out: Path, names=None, dpi: int = 100) -> list[Path]:
    """Write the named figures (default: all) as ``out/<name>.png``; returns the paths."""
    plt = _pyplot()
    names = list(FIGURES) if not names else list(names)
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        raise ValueError(f"unknown figure {unknown[0]!r}; figures: {', '.join(FIGURES)}")
    model = derivations.load("scorbot_er7")
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name in names:
        figure = FIGURES[name](plt, model)
        path = out / f"{name}.png"
        figure.savefig(path, dpi=dpi)
        plt.close(figure)
        written.append(path)
    return written


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m codegen.plots", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="plots", help="folder for the PNG files (default: plots)")
    parser.add_argument("--only", nargs="*", metavar="FIGURE", help=f"figures to draw: {', '.join(FIGURES)}")
    parser.add_argument("--dpi", type=int, default=100, help="resolution (default 100)")
    args = parser.parse_args(argv)
    try:
        for path in write_all(Path(args.out), args.only, args.dpi):
            print(path)
    except ValueError as exc:
        print(f"codegen.plots: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
