"""Time budgets for symbolic work that could run long.

SymPy has no cancellation, so a budget is enforced with an interval timer
(``SIGALRM``): when the earliest open budget runs out, :class:`BudgetExceeded`
is raised inside whatever SymPy call is running, naming the stage.  Budgets
nest (the whole derivation has one, factoring ``det J`` for the LaTeX a shorter
one inside it); the timer is always set for the earliest deadline.

Only the main thread of a process may own ``SIGALRM``; elsewhere (a thread of a
host application) :func:`budget` still records the stage but cannot interrupt,
and says so in :data:`ENFORCED`.

>>> with budget(120, "deriving ur5"):
...     with budget(5, "factoring det J"):
...         pass
"""
from __future__ import annotations

import contextlib
import functools
import resource
import signal
import sys
import threading
import time

__all__ = ["BudgetExceeded", "MemoryCapExceeded", "budget", "memory_cap", "remaining", "set_stage", "stage", "ENFORCED",
           "degraded"]


class _Stopped(Exception):
    """Work stopped at a limit: ``what`` names the work and ``stage`` the step it was in (see
    :func:`set_stage`), when one was set."""

    def __init__(self, what: str, limit: str, stage: str | None = None):
        where = f" while {stage}" if stage else ""
        super().__init__(f"{what}: stopped {limit}{where}")
        self.what = what
        self.stage = stage


class BudgetExceeded(_Stopped):
    """A time budget of ``seconds`` ran out."""

    def __init__(self, what: str, seconds: float, stage: str | None = None):
        super().__init__(what, f"after its time budget of {seconds:g} s", stage)
        self.seconds = seconds


class MemoryCapExceeded(_Stopped):
    """The body of :func:`memory_cap` asked for more than its ``gib`` GiB."""

    def __init__(self, what: str, gib: float, stage: str | None = None):
        super().__init__(what, f"at its memory cap of {gib:g} GiB", stage)
        self.gib = gib


# The step now running, for the message of a budget that runs out (set_stage).
_stage: str | None = None


def set_stage(text: str | None) -> str | None:
    """Name the step now running (``"deriving the rate kinematics"``), for budget messages; returns
    the name it replaces, for the caller to put back (see :func:`stage`)."""
    global _stage
    previous, _stage = _stage, text
    return previous


@contextlib.contextmanager
def stage(text: str):
    """Name the step the body runs, and put back the enclosing step's name after it, so that a
    budget running out between two nested steps still names where it stopped."""
    global _left_by, _left_stage
    previous = set_stage(text)
    try:
        yield
    except BaseException as exc:
        # The innermost step an error left, for a memory cap that reports it after the steps have
        # closed.  Two plain assignments: at the cap there may be no memory for anything more.
        if _capped and _left_by is not exc:
            _left_by, _left_stage = exc, text
        raise
    finally:
        set_stage(previous)


# Under a memory cap: the last error to leave a step, and that step (see stage).
_capped = False
_left_by: BaseException | None = None
_left_stage: str | None = None


class _Clock:
    """One clock budgets may count: its time, the interval timer that counts it and that timer's
    signal, and its open budgets, outermost first: (deadline on this clock, stage, seconds)."""

    def __init__(self, now, timer: int, signum: int):
        self.now, self.timer, self.signum = now, timer, signum
        self.open: list[tuple[float, str, float]] = []

    def arm(self):
        """Set the timer for the earliest open deadline (or clear it)."""
        if not self.open:
            signal.setitimer(self.timer, 0)
            return
        signal.setitimer(self.timer, max(min(entry[0] for entry in self.open) - self.now(), 1e-3))

    def on_signal(self, signum, frame):
        now = self.now()
        expired = [entry for entry in self.open if entry[0] <= now + 1e-3]
        if not expired:
            self.arm()  # a late signal for a budget already closed: wait for the next deadline
            return
        deadline, what, seconds = min(expired)
        raise BudgetExceeded(what, seconds, _stage)


# "wall": the time the user waits (SIGALRM); "cpu": this process's CPU time (SIGPROF).
_CLOCKS = {"wall": _Clock(time.monotonic, signal.ITIMER_REAL, signal.SIGALRM),
           "cpu": _Clock(time.process_time, signal.ITIMER_PROF, signal.SIGPROF)}


# How many results a budget has cut short so far in this process (degraded): a derivation that
# caught a BudgetExceeded and went on without the part it was computing (an arm left without
# ik after 10 s) must not be cached, or a later run on an idle machine would serve it for good.
degradations = 0


def degraded(reason: str) -> None:
    """Record that a result was cut short by a budget (``reason`` for the record)."""
    global degradations
    degradations += 1


def _enforceable() -> bool:
    return threading.current_thread() is threading.main_thread() and hasattr(signal, "setitimer")


ENFORCED = _enforceable()


def remaining() -> float | None:
    """Seconds left in the tightest open budget, or None when there is none."""
    wall = _CLOCKS["wall"]
    if not wall.open:
        return None
    return max(min(entry[0] for entry in wall.open) - wall.now(), 0.0)


@contextlib.contextmanager
def budget(seconds: float | None, stage: str, clock: str = "wall"):
    """Run the body within ``seconds`` (None: no limit of its own), or raise :class:`BudgetExceeded`.

    ``clock="wall"`` counts the time the user waits (``SIGALRM``); ``clock="cpu"`` the CPU time
    of this process (``SIGPROF``), for a decision that must not depend on how busy the machine
    is: the automatic ik's 10 s, whose verdict (a closed form or not) shapes the generated code.
    """
    if clock not in ("wall", "cpu"):
        raise ValueError(f"a budget's clock is 'wall' or 'cpu', got {clock!r}")
    if seconds is None or not _enforceable():
        yield
        return
    if not seconds > 0:
        raise ValueError(f"a time budget must be positive, got {seconds!r}")
    chosen = _CLOCKS[clock]
    previous = signal.getsignal(chosen.signum)
    if previous != chosen.on_signal:
        signal.signal(chosen.signum, chosen.on_signal)
    entry = (chosen.now() + seconds, stage, seconds)
    chosen.open.append(entry)
    try:
        chosen.arm()
        yield
    finally:
        chosen.open.remove(entry)
        # Every clock, not only this one: a budget of the other clock that ran out while this body
        # ran was raised into it, and this budget's catcher may have taken it for its own (the
        # automatic ik's CPU-time budget inside the command's --time-limit): armed again, its
        # deadline passed, it is raised once more as soon as this budget closes.
        chosen.arm()
        for other in _CLOCKS.values():
            if other is not chosen and other.open:
                other.arm()
        if previous != chosen.on_signal:
            signal.signal(chosen.signum, previous)


def _address_space() -> int | None:
    """This process's virtual memory size in bytes (Linux's /proc), or None where unknown."""
    try:
        with open("/proc/self/statm") as handle:
            return int(handle.read().split()[0]) * resource.getpagesize()
    except (OSError, ValueError, IndexError):
        return None


# How near the cap the process must be for a failure to count as the cap's (a request of up to
# this many bytes may have failed).
_CAP_MARGIN = 64 * 2**20


def _failed_in(exc: BaseException) -> str | None:
    """The step ``exc`` was raised in: recorded by :func:`stage` on its way out (also where, at the cap,
    unwinding a step raised a fresh MemoryError, whose context is the one the step recorded), else the
    current one, else the last a failure left."""
    seen = exc
    while seen is not None:
        if seen is _left_by:
            return _left_stage
        seen = seen.__context__
    return _stage or (_left_stage if _left_by is not None else None)


@functools.lru_cache(maxsize=None)
def _prime_blas() -> None:
    """One matrix product large enough for every BLAS thread, before any cap: OpenBLAS takes its
    work buffers at its first product in each thread, and where it cannot it ends the process with
    status 1 ("Memory allocation still failed after 10 retries"), not a MemoryError (numpy's small
    matrix products in the automatic ik's branch naming, under a cap of 10 MiB)."""
    import numpy
    block = numpy.ones((256, 256))
    block @ block


@contextlib.contextmanager
def memory_cap(gib: float | None, stage: str):
    """Run the body with at most ``gib`` GiB of address space more than the process holds now
    (None: no cap), or raise :class:`MemoryCapExceeded` naming the stage.

    The cap is the soft ``RLIMIT_AS`` of this process, lowered for the body and put back after
    it, so that compilers started later are not bound by it.  Where the limit or the process
    size cannot be read (not Linux), the body runs uncapped.
    """
    global _capped, _left_by
    if gib is None:
        yield
        return
    if not gib > 0:
        raise ValueError(f"a memory cap must be positive, got {gib!r}")
    _prime_blas()
    size = _address_space()
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    if size is None:
        yield
        return
    cap = size + int(gib * 2**30)
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    if soft != resource.RLIM_INFINITY:
        cap = min(cap, soft)
    resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    failure = None
    _capped, _left_by = True, None
    # At the cap, a generator that SymPy was iterating may fail to close for want of memory, and
    # Python would print "Exception ignored in: <generator ...>" and a traceback on the way out:
    # that MemoryError is the cap's, and the cap's message says so.
    unraisable = sys.unraisablehook
    sys.unraisablehook = lambda report: None if isinstance(report.exc_value, MemoryError) else unraisable(report)
    try:
        yield
    except MemoryError as exc:
        failure = exc
    except Exception as exc:
        # An allocation that fails inside a C extension can surface as another error (a
        # SystemError with no exception set, say): at the cap, it is the cap's.
        try:
            now = _address_space()
        except MemoryError:  # reading the size needs memory too: no room left is the cap's answer
            now = cap
        if now is None or now < cap - _CAP_MARGIN:
            raise
        failure = exc
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
        sys.unraisablehook = unraisable
        _capped = False
    # Built only now, with the limit lifted: the message and its stage need memory too.
    if failure is not None:
        where, _left_by = _failed_in(failure), None
        raise MemoryCapExceeded(stage, gib, where) from (None if isinstance(failure, MemoryError) else failure)
    _left_by = None
