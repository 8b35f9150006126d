"""Calling the engine safely, for every entry point: argument ranges, memory budgets, and engine
calls run so that Ctrl-C (or a failing progress callback) cancels them promptly.

See docs/guarantees.md for what these promise.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from quadrs import _core

T = TypeVar("T")

#: Seconds between polls of a running engine call (the main thread answers Ctrl-C at this pace).
POLL_SECONDS = 0.2
#: Seeds and gust stream indices are unsigned 64-bit integers.
U64_MAX = 2**64 - 1
#: Realisation labels are stored as signed 64-bit integers (the ``realisation`` column).
I64_MAX = 2**63 - 1
#: Most worker threads one call may ask for.
MAX_WORKERS = 4096
#: The controllers the engine flies, by name (its list: one vocabulary for the package).
CONTROLLERS: tuple[str, ...] = tuple(_core.CONTROLLER_NAMES)
#: The paper's two laws: what a batch, a sweep and ``--controller both`` fly unless told
#: otherwise (the paper's Table 3 compares them; the other laws are asked for by name).
PAPER_CONTROLLERS: tuple[str, ...] = ("pd", "smc")
#: Signals held back while finished work is kept (Ctrl-C and what the CLI treats like it).
_DEFERRED = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def deferred_signals(
    deliver: bool = True, on_signal: Callable[[int], None] | None = None
) -> Iterator[list[int]]:
    """Hold Ctrl-C and SIGTERM back for the duration of the block (only on the main thread,
    where Python runs signal handlers; elsewhere a no-op), calling ``on_signal(signum)`` as
    each arrives (e.g. to cancel the engine). Yields the list of the signals held. On exit
    the first one is delivered to the handler it would have met; with ``deliver=False`` the
    caller acts on the list instead (marks the work interrupted): the handler still runs, so
    it can note the signal (the command line's exit status for SIGTERM), but the
    KeyboardInterrupt it raises is dropped. No KeyboardInterrupt is ever raised inside the
    block: one raised inside a lock or an Event's wait can leave it broken. A signal the
    process ignores (``nohup``, a shell's background job) stays ignored: it is not held, so
    it neither cancels nor interrupts anything."""
    caught: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield caught
        return
    frames: list[Any] = []
    previous: dict[int, Any] = {}

    def hold(signum: int, frame: Any) -> None:
        caught.append(signum)
        frames.append(frame)
        if on_signal is not None:
            on_signal(signum)

    for sig in _DEFERRED:
        if signal.getsignal(sig) == signal.SIG_IGN:
            continue
        try:
            previous[sig] = signal.signal(sig, hold)
        except (ValueError, OSError):  # not installable here
            pass
    try:
        yield caught
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for signum, frame in zip(caught[:1], frames[:1], strict=True):
            handler = previous.get(signum)
            if callable(handler):
                if deliver:
                    handler(signum, frame)
                else:
                    with contextlib.suppress(KeyboardInterrupt):
                        handler(signum, frame)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(signum)


def check_controller(name: str) -> str:
    """``name`` if the engine has such a controller, else ValueError naming the choices."""
    if name not in CONTROLLERS:
        raise ValueError(f"controller must be one of {CONTROLLERS}, got {name!r}")
    return name


def loop_rates(scenario: Any, controller: str) -> tuple[float, float, float]:
    """Hz, the position, attitude and inner loops' rates ``controller`` flies in
    ``scenario``: the engine's schedule (``Engine.loop_steps``: the ``controller.*_rate``
    keys where set, else the law's own rate rounded to whole steps), one update every
    ``n`` steps being ``1 / (n dt)`` Hz; a loop run every step flies at the step's rate."""
    dt = float(scenario.get("integrator.dt"))
    a, b, c = (1.0 / (n * dt) for n in scenario.engine.loop_steps(controller))
    return a, b, c


def is_sampled(scenario: Any, controller: str) -> bool:
    """Whether some loop of ``controller`` runs slower than every step (docs/model.md, "Loop
    rates"): the engine's own schedule (``Engine.loop_steps``: a law's own rate rounded to
    whole steps)."""
    return any(n > 1 for n in scenario.engine.loop_steps(controller))


def check_int(name: str, value: Any, low: int = 0, high: int = U64_MAX) -> int:
    """``value`` as an int in [low, high], else ValueError naming ``name`` and the value."""
    if isinstance(value, bool) or not isinstance(value, int):
        try:
            as_int = int(value)
        except (TypeError, ValueError, OverflowError):
            raise ValueError(f"{name} must be a whole number, got {value!r}") from None
        if as_int != value:
            raise ValueError(f"{name} must be a whole number, got {value!r}")
        value = as_int
    if not low <= value <= high:
        raise ValueError(f"{name} must be between {low} and {high}, got {value}")
    return int(value)


def default_workers() -> int:
    """Cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def check_labels(first: int, count: int) -> None:
    """Realisations first .. first + count - 1 must all fit the int64 ``realisation`` column."""
    if first + count - 1 > I64_MAX:
        raise ValueError(
            f"first + runs - 1 must be at most 2**63 - 1 (realisation labels are int64), "
            f"got first = {first}, runs = {count}"
        )


def available_memory() -> int | None:
    """Bytes of memory available now (None where the platform does not say)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(what: str, nbytes: int) -> None:
    """MemoryError naming ``what`` if ``nbytes`` exceed the memory available now."""
    free = available_memory()
    if free is not None and nbytes > free:
        raise MemoryError(
            f"{what} needs about {nbytes / 2**30:.3g} GiB, more than the "
            f"{free / 2**30:.3g} GiB of memory available"
        )


def run_cancellable(
    work: Callable[[], T],
    progress: _core.Progress,
    on_poll: Callable[[], None] | None = None,
) -> tuple[T, bool]:
    """Run ``work()`` (an engine call that releases the GIL and watches ``progress``'s cancel
    flag) on a thread while this one polls every POLL_SECONDS, calling ``on_poll``.

    Ctrl-C cancels the work and waits for it (further Ctrl-Cs meanwhile are ignored: the
    cancel takes milliseconds); the result is then returned with ``interrupted=True``. If
    ``on_poll`` raises (a broken progress bar or stderr), the work is cancelled too and the
    error re-raised: nothing is left running in the background. Raises ``work``'s own error,
    and KeyboardInterrupt if it was interrupted before producing anything."""
    box: dict[str, Any] = {}
    finished = threading.Event()

    def run() -> None:
        try:
            box["out"] = work()
        except BaseException as e:  # re-raised on the calling thread
            box["error"] = e
        finally:
            finished.set()

    def cancel_and_wait() -> None:
        progress.cancel()
        while True:
            try:
                # Poll an Event, not Thread.join: an interrupted join can mark a live thread
                # as finished.
                if not thread.is_alive() or finished.wait(POLL_SECONDS):
                    return
            except KeyboardInterrupt:
                continue

    thread = threading.Thread(target=run, name="quadrs-engine", daemon=True)
    # Ctrl-C (and SIGTERM) cancel the engine from the handler itself: no KeyboardInterrupt is
    # raised into this wait, where a second one could break the Event's lock.
    try:
        with deferred_signals(deliver=False, on_signal=lambda _: progress.cancel()) as caught:
            thread.start()
            while not finished.wait(POLL_SECONDS):
                if on_poll is not None:
                    on_poll()
    except KeyboardInterrupt:  # only off the main thread, or before the handlers were set
        caught = [signal.SIGINT]
        cancel_and_wait()
    except BaseException:
        cancel_and_wait()
        raise
    interrupted = bool(caught)
    if "error" in box:
        raise box["error"]
    if "out" not in box:  # interrupted before the work began
        raise KeyboardInterrupt
    return box["out"], interrupted
