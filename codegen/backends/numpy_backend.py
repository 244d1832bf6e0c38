"""The numpy backend: a NumPyPrinter subclass and the module template."""
from __future__ import annotations

import sympy as sp
from sympy.printing.numpy import NumPyPrinter

from . import TEMPLATES, ExactArithmeticMixin, remembered_precedence

__all__ = ["NumpyKernelPrinter", "render"]


class NumpyKernelPrinter(ExactArithmeticMixin, NumPyPrinter):
    """Prints element-wise numpy code (every input may be a batch of values)."""

    _sqrt_name = "numpy.sqrt"

    def __init__(self, memo: dict | None = None):
        super().__init__({"fully_qualified_modules": True, "allow_unknown_functions": False})
        self._memo = {} if memo is None else memo

    def doprint(self, expr, assign_to=None):
        """``NumPyPrinter.doprint``, remembered in ``memo`` (a render's worker processes print ahead)."""
        if assign_to is not None:
            return super().doprint(expr, assign_to)
        text = self._memo.get(expr)
        if text is None:
            with remembered_precedence():
                text = self._memo[expr] = super().doprint(expr)
        return text

    def _nested(self, function, args):
        printed = [self._print(a) for a in args]
        text = printed[0]
        for other in printed[1:]:
            text = f"{function}({text}, {other})"
        return text

    def _print_Min(self, expr):
        return self._nested("numpy.minimum", expr.args)

    def _print_Max(self, expr):
        return self._nested("numpy.maximum", expr.args)

    def _print_ClampUnit(self, expr):
        return f"_runtime.snap_unit({self._print(expr.args[0])})"

    def _print_Ramp(self, expr):
        return self._print(expr.as_min_max())

    def _print_And(self, expr):
        return self._nested("numpy.logical_and", expr.args)

    def _print_Or(self, expr):
        return self._nested("numpy.logical_or", expr.args)

    def _print_Not(self, expr):
        return f"numpy.logical_not({self._print(expr.args[0])})"

    def _print_Piecewise(self, expr):
        # numpy.where, nested from the last piece: clearer than numpy.select and the
        # same element-wise choice; a Piecewise without a final True piece is refused.
        if expr.args[-1].cond is not sp.true:
            raise ValueError(f"cannot print a Piecewise without a catch-all piece: {expr}")
        text = self._print(expr.args[-1].expr)
        for value, condition in reversed(expr.args[:-1]):
            text = f"numpy.where({self._print(condition)}, {self._print(value)}, {text})"
        return text

    def _print_WrapAngle(self, expr):
        return f"_runtime.wrap_angle({self._print(expr.args[0])})"

    def _print_BooleanTrue(self, expr):
        return "True"

    def _print_BooleanFalse(self, expr):
        return "False"


def render(context: dict) -> dict[str, str]:
    """Files of the numpy backend, by name, for one robot."""
    printer = NumpyKernelPrinter(context.get("printed", {}).get("numpy"))
    return {
        "numpy_kernels.py": TEMPLATES.get_template("numpy_kernels.py.j2").render(context, printer=printer),
    }
