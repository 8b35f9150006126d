"""What every ``quadrs`` subcommand module shares: the exit statuses, the bad-input error, the
Dask client of ``--scheduler``, and the options several commands take, each declared once
here (a function that adds it to a command's parser) with the reading of its value. Imported
by :mod:`quadrs.cli.main` and the command modules beside it alike, so that none of them
imports another."""

from __future__ import annotations

import argparse
import contextlib
import shutil
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

__all__ = [
    "EXIT_FAIL",
    "EXIT_INTERRUPT",
    "EXIT_OK",
    "EXIT_TERMINATED",
    "EXIT_USAGE",
    "BadInput",
    "batch_options",
    "batch_scope",
    "batch_status",
    "check_positive",
    "command_parser",
    "controller_names",
    "controller_option",
    "controllers_option",
    "dask_client",
    "import_in_background",
    "limit_option",
    "limit_options",
    "no_progress_option",
    "one_line",
    "paper_controllers",
    "parquet_out_option",
    "passed",
    "plots_option",
    "progress",
    "report_width",
    "scenario_options",
    "scheduler_option",
    "seed_and_workers",
    "seed_option",
    "table_options",
    "workers_option",
]

#: Exit statuses of every subcommand: done; done but a check failed (or nothing was saved);
#: bad input (one line on stderr); interrupted (Ctrl-C, what finished is saved); terminated.
EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPT, EXIT_TERMINATED = 0, 1, 2, 130, 143


class BadInput(ValueError):
    """Bad command-line input caught by the CLI itself (not by the scenario)."""


@contextlib.contextmanager
def dask_client(address: str | None) -> Iterator[Any]:
    """A Dask client for ``--scheduler`` (None without it): Dask is imported only then."""
    if address is None:
        yield None
        return
    try:
        import dask.distributed  # noqa: F401
    except ImportError:
        raise BadInput("--scheduler needs Dask: pip install 'quadrs[dask]'") from None
    with connect(address) as client:
        yield client


class ExitAfterDask:
    """A Ctrl-C or SIGTERM while the process exits after a command that used ``--scheduler``:
    Dask's exit handlers (its client's loop and threads) ran under Python's default handler,
    so the signal raised a KeyboardInterrupt traceback inside them and the status stayed 0.
    :meth:`register` (before Dask is imported, so that this handler runs after Dask's) and
    :meth:`hold` (when the command is done) note such a signal instead and end the process
    with 130 (143 for SIGTERM) once Dask's handlers are done. Only for the console command:
    a caller of :func:`quadrs.cli.main.main` keeps its own signal handling."""

    def __init__(self) -> None:
        self.caught: list[int] = []
        self.registered = False

    def register(self) -> None:
        import atexit

        if not self.registered:
            self.registered = True
            atexit.register(self._exit)

    def hold(self) -> None:
        import signal

        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, lambda signum, frame: self.caught.append(signum))

    def _exit(self) -> None:
        import os
        import signal

        if self.caught:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(EXIT_TERMINATED if self.caught[0] == signal.SIGTERM else EXIT_INTERRUPT)


#: The console command's hold on signals at its exit (``quadrs.cli.main.main``).
exit_after_dask = ExitAfterDask()


#: s, the longest the connection to ``--scheduler`` (the handshake included) may take.
CONNECT_TIMEOUT = 10.0


def _check_address(address: str) -> None:
    """BadInput, at once, for an address no connection can reach, read by Dask's own parser (a
    protocol it does not know, a port that is no number, an inproc:// address no scheduler of
    this process listens at): a loaded machine took more than the connection's timeout to find
    that by trying."""
    from distributed.comm import registry
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, location = parse_address(address)
        registry.get_backend(scheme)
        if scheme in ("tcp", "tls"):
            parse_host_port(location)
        if scheme == "inproc" and not _listened_in_process(location):
            raise ValueError("no scheduler of this process listens there")
    except (ValueError, TypeError) as e:
        text = str(e).strip()
        why = text.splitlines()[0] if text else type(e).__name__
        raise BadInput(f"--scheduler {address}: cannot connect ({why})") from None


def _listened_in_process(location: str) -> bool:
    """Whether a listener of this process has the inproc:// address ``location`` (Dask's
    in-process registry; ValueError for an address of another process or no such address)."""
    from distributed.comm import inproc

    manager = getattr(inproc, "global_manager", None)
    if manager is None:  # (another Dask: left to the connection)
        return True
    return manager.get_listener_for(location) is not None


@contextlib.contextmanager
def connect(address: str, timeout: float | None = None) -> Iterator[Any]:
    """A Dask client of the scheduler at ``address``, connected within ``timeout`` s or
    BadInput: Dask's own timeout covers the TCP connect only, so a server that accepts and
    never answers (or answers in another protocol) would hang it; the client is made on a
    daemon thread that is left behind when it does not finish in time."""
    from dask.distributed import Client

    _check_address(address)
    timeout = CONNECT_TIMEOUT if timeout is None else timeout
    made: dict[str, Any] = {}

    def make() -> None:
        try:
            made["client"] = Client(address, timeout=f"{timeout:g}s")
        except BaseException as e:  # handed to the caller's thread
            made["error"] = e

    thread = threading.Thread(target=make, name="quadrs --scheduler connect", daemon=True)
    thread.start()
    thread.join(timeout + 1.0)
    if thread.is_alive():
        raise BadInput(f"--scheduler {address}: no answer within {timeout:g} s (the address "
                       "accepts connections but no Dask scheduler answers there)")  # fmt: skip
    error = made.get("error")
    if isinstance(error, (MemoryError, OverflowError, UnicodeDecodeError)):
        # Dask read another protocol's answer (an HTTP server's) as a frame's length.
        raise BadInput(f"--scheduler {address}: something answers there, but not a Dask "
                       "scheduler (an HTTP server? give the scheduler's tcp:// address, port "
                       "8786 by default)") from None  # fmt: skip
    if error is not None:
        # (a bad port, an unknown protocol, TLS without a context, inproc:// from outside)
        if not isinstance(error, Exception):
            raise error  # KeyboardInterrupt, SystemExit
        text = str(error).strip()
        why = text.splitlines()[0] if text else type(error).__name__
        raise BadInput(f"--scheduler {address}: cannot connect ({why})") from None
    with made["client"] as client:
        yield client


class BatchScope:
    """What a command that flies a batch and saves it holds while it does: the Dask client
    of ``--scheduler`` (None without it), and from :meth:`flown` on, Ctrl-C and SIGTERM."""

    def __init__(self, client: Any, keeping: contextlib.ExitStack) -> None:
        self.client = client
        self._keeping = keeping

    def flown(self) -> None:
        """The batch is over: from here a Ctrl-C or SIGTERM (a second one, after the one that
        stopped the batch) waits until the scope ends, what finished saved, then ends the
        command (status 130 or 143)."""
        from quadrs.engine.calls import deferred_signals

        self._keeping.enter_context(deferred_signals())

    def keywords(self, args: argparse.Namespace) -> dict[str, Any]:
        """The batch's options as the library's keywords: ``runs``, ``seed``, ``workers``,
        ``progress`` (bars on a terminal only) and the ``client`` of ``--scheduler``."""
        return {**passed(args, "runs", "seed", "workers"), "progress": progress(args),
                "client": self.client}  # fmt: skip


@contextlib.contextmanager
def batch_scope(address: str | None) -> Iterator[BatchScope]:
    """The scope of a batch command: fly (``client=scope.client``), call ``scope.flown()``,
    save; the client closes, then a signal held meanwhile ends the command."""
    with contextlib.ExitStack() as keeping, dask_client(address) as client:
        yield BatchScope(client, keeping)


def import_in_background(module: str) -> threading.Thread:
    """Start importing ``module`` on a daemon thread: while the engine flies (it releases the
    GIL), the import's time is off the command's critical path. The command imports it again
    where it needs it, as usual: the import system then waits for this import and gives the
    same module, or raises its error there (an error here is left for that import)."""
    import importlib

    def load() -> None:
        with contextlib.suppress(Exception):
            importlib.import_module(module)

    thread = threading.Thread(target=load, name=f"import {module}", daemon=True)
    thread.start()
    return thread


#: The narrowest and widest the reports are laid out for (columns).
REPORT_WIDTH = (60, 100)


def report_width() -> int:
    """Columns for a report's tables and text: the terminal's (``COLUMNS`` first, as
    ``shutil.get_terminal_size`` reads it) within ``REPORT_WIDTH``; the widest when the
    output is not a terminal (a file keeps the full tables)."""
    narrowest, widest = REPORT_WIDTH
    return max(narrowest, min(widest, shutil.get_terminal_size((widest, 24)).columns))


def note(text: str) -> None:
    """A note or warning on stderr; on a terminal wrapped to the report's width (continuation
    lines indented two spaces, so each note still starts its own line; a word longer than
    the width, a path, is kept whole), into a file or a pipe one line a note, as a log is
    searched. Errors stay one line (``quadrs: error: ...``)."""
    import textwrap

    from quadrs.present.terminal import terminal_text

    text = terminal_text(text)
    if sys.stderr.isatty():
        text = textwrap.fill(text, report_width(), subsequent_indent="  ",
                             break_long_words=False, break_on_hyphens=False)  # fmt: skip
    print(text, file=sys.stderr, flush=True)


def one_line(text: str) -> str:
    """A message's lines joined into one (``quadrs: warning: ...`` and errors alike)."""
    return "; ".join(line.strip() for line in text.strip().splitlines() if line.strip())


def batch_status(result: Any, saved: bool) -> int:
    """A batch command's exit status: 130 if interrupted, else 0 if its outputs were saved
    and 1 if not."""
    return EXIT_INTERRUPT if result.interrupted else EXIT_OK if saved else EXIT_FAIL


def passed(args: argparse.Namespace, *names: str) -> dict[str, Any]:
    """The options ``names`` as keywords of the same names: options the library takes as
    they are given."""
    return {name: getattr(args, name) for name in names}


def check_positive(name: str, value: int | None, minimum: int = 1) -> None:
    """BadInput unless an integer option's ``value`` (None: not given) is at least
    ``minimum``."""
    if value is not None and value < minimum:
        raise BadInput(f"{name} must be >= {minimum}, got {value}")


def progress(args: argparse.Namespace) -> bool:
    """Progress bars on a terminal only: none in logs, pipes or CI output."""
    return not args.no_progress and sys.stderr.isatty()


def command_parser(
    sub: Any, add: Callable[..., None], *parents: argparse.ArgumentParser
) -> argparse.ArgumentParser:
    """The parser of ``quadrs NAME``, as its ``add_NAME`` function declares it: the name after
    ``add_``, the one line ``quadrs --help`` lists its first paragraph, the description of
    ``quadrs NAME --help`` the rest (the docstring is the command's help); ``parents``: the
    options it shares (the scenario's)."""
    doc = (add.__doc__ or "").split("\n\n", 1)
    summary, description = (" ".join(part.split()) for part in (*doc, "")[:2])
    return sub.add_parser(
        add.__name__.removeprefix("add_"),
        parents=list(parents),
        help=summary,
        description=description or None,
    )


# -- the scenario's options -------------------------------------------------------------------
def scenario_options(default_preset: str = "paper") -> argparse.ArgumentParser:
    """The scenario's options (``--preset``, ``--scenario``, ``--set``, ``--disperse``) as a
    parent parser, their help naming the command's own default preset (mission: delivery,
    every other command: paper)."""
    from quadrs.scenario.dispersion import DISTRIBUTIONS
    from quadrs.scenario.scenario import presets

    common = argparse.ArgumentParser(add_help=False)
    g = common.add_argument_group("scenario")
    g.add_argument(
        "--preset",
        default=None,
        choices=presets(),
        help=f"start from a shipped preset (default: {default_preset})",
    )
    g.add_argument(
        "--scenario",
        metavar="FILE.toml",
        type=Path,
        help='start from a scenario file instead (it may begin with base = "paper" and give '
        "only what differs)",
    )
    g.add_argument(
        "--set",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        dest="overrides",
        help="override one dotted key, repeatable; VALUE in TOML syntax and SI units, e.g. "
        "payload.mass=0.44 (kg), gust.w20=15 (m/s), payload.natural_frequency=4 (Hz), "
        "integrator.duration=10 (s), 'trajectory.interpolation=\"min_jerk\"'; "
        "`quadrs scenario keys` lists every key with its value and unit",
    )
    g.add_argument(
        "--disperse",
        metavar="KEY=DIST(ARGS)",
        action="append",
        default=[],
        dest="dispersions",
        help="give a numeric key a distribution, repeatable: "
        + ", ".join(f"{d}({','.join(p)})" for d, p in DISTRIBUTIONS.items())
        + " (lognormal's of the logarithm); e.g. payload.mass=uniform(0.1,0.4); "
        "see docs/dispersions.md",
    )
    return common


# -- options of batches -----------------------------------------------------------------------
def seed_option(p: argparse.ArgumentParser, help: str = "master seed (default: 0)") -> None:
    """``--seed S``, 0 by default."""
    p.add_argument("--seed", type=int, default=0, metavar="S", help=help)


def workers_option(
    p: argparse.ArgumentParser,
    help: str = "worker threads (default: every core this process may use)",
) -> None:
    """``--workers W``: threads, every core by default (None)."""
    p.add_argument("--workers", type=int, default=None, metavar="W", help=help)


def seed_and_workers(p: argparse.ArgumentParser) -> None:
    """The options every batch command takes: ``--seed`` and ``--workers``."""
    seed_option(p)
    workers_option(p)


def scheduler_option(
    p: argparse.ArgumentParser,
    help: str = "fly on a Dask cluster, e.g. tcp://10.0.0.5:8786, with the same result as here "
    "(needs pip install quadrs[dask])",
) -> None:
    """``--scheduler ADDRESS``: the command's flights as tasks on a Dask cluster."""
    p.add_argument("--scheduler", metavar="ADDRESS", help=help)


def no_progress_option(
    p: argparse.ArgumentParser,
    help: str = "no progress bar (there is none anyway unless stderr is a terminal)",
) -> None:
    """``--no-progress``."""
    p.add_argument("--no-progress", action="store_true", help=help)


def path_option(p: argparse.ArgumentParser, flag: str, metavar: str, help: str) -> None:
    """An option naming a file or folder to write (``--trace FILE``, ``--safety-case FILE``):
    a Path, None unless given."""
    p.add_argument(flag, type=Path, default=None, metavar=metavar, help=help)


def parquet_out_option(p: argparse.ArgumentParser, help: str) -> None:
    """``--out FILE.parquet``: where the command saves what it found."""
    path_option(p, "--out", "FILE.parquet", help)


def plots_option(p: argparse.ArgumentParser, help: str) -> None:
    """``--plots DIR``: where the command writes its figures."""
    path_option(p, "--plots", "DIR", help)


def controller_names() -> tuple[str, ...]:
    """The engine's controllers (the package's one list, quadrs.engine.calls.CONTROLLERS)."""
    from quadrs.engine.calls import CONTROLLERS

    return CONTROLLERS


def paper_controllers() -> tuple[str, ...]:
    """The paper's pair, the default of the batch commands (quadrs.engine.calls)."""
    from quadrs.engine.calls import PAPER_CONTROLLERS

    return PAPER_CONTROLLERS


def _controllers(text: str) -> tuple[str, ...]:
    names = tuple(c.strip() for c in text.split(",") if c.strip())
    known = controller_names()
    bad = [c for c in names if c not in known]
    if bad or not names:
        raise argparse.ArgumentTypeError(f"controllers are {' and/or '.join(known)}, got {text!r}")
    return names


def controller_option(p: argparse.ArgumentParser, both: bool = False) -> None:
    """``--controller``: one law, smc by default (``run``, ``tune``); ``both``: or both of
    the paper's, the default (``stability``, ``linearize``)."""
    if both:
        p.add_argument(
            "--controller",
            choices=(*controller_names(), "both"),
            default="both",
            help="a law, or both of the paper's (pd and smc; the default)",
        )
    else:
        p.add_argument(
            "--controller",
            choices=controller_names(),
            default="smc",
            help="controller (default: smc)",
        )


def controllers_option(p: argparse.ArgumentParser, what: str) -> None:
    """``--controllers LIST``: comma-separated controllers, the paper's pair by default;
    ``what`` begins the help ("comma-separated controllers to fly")."""
    p.add_argument(
        "--controllers",
        type=_controllers,
        default=paper_controllers(),
        metavar="LIST",
        help=f"{what}, of {','.join(controller_names())} "
        f"(default: the paper's {','.join(paper_controllers())})",
    )


def _values(text: str) -> list[Any]:
    """A list of values: comma-separated TOML values, or a TOML array (``--values``,
    ``--frequencies``, ``--masses``). Its name is argparse's word for a value it cannot read."""
    from quadrs.scenario.scenario import parse_value

    text = text.strip()
    if text.startswith("["):
        value = parse_value(text)
        if not isinstance(value, list):
            raise argparse.ArgumentTypeError(f"not a TOML array: {text!r}")
        return value
    values = [parse_value(v.strip()) for v in text.split(",") if v.strip()]
    if not values:
        raise argparse.ArgumentTypeError("no values given")
    return values


def batch_options(p: argparse.ArgumentParser, runs: int, out_help: str) -> None:
    """The options of a paired Monte Carlo batch (``mc``, ``sweep``): ``--runs`` (``runs`` by
    default), ``--seed``, ``--workers``, ``--controllers``, ``--out`` (``out_help``),
    ``--no-progress``, ``--scheduler`` and ``--sampling``."""
    from quadrs.scenario.dispersion import SAMPLINGS

    p.add_argument(
        "--runs",
        type=int,
        default=runs,
        metavar="N",
        help="gust realisations (each flown by every controller) (default: %(default)s)",
    )
    seed_and_workers(p)
    controllers_option(p, "comma-separated controllers to fly")
    parquet_out_option(p, out_help)
    no_progress_option(p)
    scheduler_option(
        p,
        help="run the chunks on a Dask cluster, e.g. tcp://10.0.0.5:8786 "
        "(needs pip install quadrs[dask])",
    )
    p.add_argument(
        "--sampling",
        choices=SAMPLINGS,
        default="random",
        help="how the values of dispersed keys are drawn: independent per realisation "
        "(random), or a stratified design over the batch (lhs, sobol) (default: random)",
    )


# -- what the tables show ---------------------------------------------------------------------
def table_options(p: argparse.ArgumentParser) -> None:
    """``--wide`` and ``--no-paper``: how Table 3 is printed."""
    p.add_argument(
        "--wide",
        action="store_true",
        help="print Table 3 in one wide row per phase with full intervals (about 190 columns)",
    )
    p.add_argument(
        "--no-paper",
        action="store_true",
        help="leave the paper's own P values out of Table 3 (they are shown for the paper "
        "preset only)",
    )


def limit_option(text: str) -> tuple[str, float]:
    """``--limit METRIC=X`` (any metric the engine names) or a bare ``X`` for max_accel, in
    ``quadrs mc``, ``sweep``, ``report`` and ``mission`` alike; X in the unit the tables show
    (degrees for swing; for an acceleration m/s², or g with a ``g`` suffix: ``2g``), returned
    in the results' unit (radians, m/s²)."""
    from quadrs.present.labels import metric_value
    from quadrs.stats.risk import parse_limit

    if "=" not in text:
        text = f"max_accel={text}"
    name, _, raw = text.partition("=")
    try:
        metric, _ = parse_limit(f"{name}=0")  # the metric's name checked
        return metric, metric_value(metric, raw.strip() or "?")
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _limit(text: str) -> tuple[str, float]:
    """``--limit`` (:func:`limit_option`)."""
    return limit_option(text)


def _half_width(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0 < value < 50:
        raise argparse.ArgumentTypeError(f"must be in (0, 50) percentage points, got {text!r}")
    return value


def limit_options(p: argparse.ArgumentParser) -> None:
    """``--limit METRIC=THRESHOLD`` (repeatable) and ``--half-width PP``: the exceedance
    tables of ``mc``, ``sweep`` and ``report``."""
    p.add_argument(
        "--limit",
        metavar="METRIC=THRESHOLD",
        action="append",
        type=_limit,
        default=[],
        help="print P(METRIC > THRESHOLD) per controller and phase with its exact 95%% "
        "interval and the runs needed for a chosen width, e.g. max_accel=2.0 (m/s^2; a bare "
        "2.0 means max_accel), max_swing=30 (degrees); "
        "repeatable; a run counts as exceeding in the phase it diverged in and later ones",
    )
    p.add_argument(
        "--half-width",
        type=_half_width,
        default=1.0,
        metavar="PP",
        help="interval half-width, in percentage points, for the runs-needed column of "
        "--limit (default: %(default)s)",
    )
