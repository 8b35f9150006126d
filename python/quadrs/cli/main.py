"""``quadrs``: the command line. This module builds the top parser and dispatches to the
command modules beside it, one per subcommand (``run``, ``mc``, ``sweep``, ``report``,
``paper``, ``stability``, ``sensitivity``, ``scenario``, ``design`` for ``tune`` and
``linearize``, ``rare``, ``mission``); the options several of them take are declared once in
:mod:`quadrs.cli.common`.

Exit status: 0 on success; 1 if an output could not be written (the results are then saved
to a recovery file whose path is printed), if ``stability`` found the closed loop unstable, or
if ``tune`` found no admissible or feasible candidate; 2 on bad input, with one line on
stderr naming the key or file; 130 on Ctrl-C and 143 on SIGTERM, after saving what had finished. Set
``QUADRS_TRACEBACK=1`` to see the full traceback of an error instead of its one-line reason.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
import warnings
from collections.abc import Callable, Iterator, Sequence
from typing import Any, NoReturn

from quadrs.cli.common import (
    EXIT_INTERRUPT,
    EXIT_OK,
    EXIT_TERMINATED,
    EXIT_USAGE,
    exit_after_dask,
    note,
    one_line,
    scenario_options,
)
from quadrs.cli.common import _limit as _limit
from quadrs.cli.mc import cmd_mc
from quadrs.cli.paper import cmd_paper
from quadrs.cli.report import cmd_report
from quadrs.cli.run import cmd_run
from quadrs.cli.scenario import cmd_scenario
from quadrs.cli.scenario_args import load_scenario, parse_distribution
from quadrs.cli.sensitivity import cmd_sensitivity, sensitivity_table
from quadrs.cli.stability import cmd_stability
from quadrs.cli.sweep import cmd_sweep
from quadrs.cli.tables import print_limits as _print_limits  # noqa: F401  (its name here before)
from quadrs.present.terminal import terminal_text

#: What this module offers. The commands it held and the steps they share are made beside it
#: and stay importable from here (``_limit`` and ``_print_limits`` too); ``tune``,
#: ``linearize``, ``rare`` and ``mission`` were in their own modules already.
__all__ = [
    "COMMANDS",
    "Parser",
    "build_parser",
    "cmd_mc",
    "cmd_paper",
    "cmd_report",
    "cmd_run",
    "cmd_scenario",
    "cmd_sensitivity",
    "cmd_stability",
    "cmd_sweep",
    "load_scenario",
    "main",
    "parse_distribution",
    "sensitivity_table",
]

#: Each subcommand, in the order ``--help`` lists them, and the module beside this one that
#: declares (``add_<command>``) and runs (``cmd_<command>``) it.
_MODULES = {
    "run": "run",
    "mc": "mc",
    "sweep": "sweep",
    "report": "report",
    "paper": "paper",
    "stability": "stability",
    "sensitivity": "sensitivity",
    "scenario": "scenario",
    "tune": "design",
    "linearize": "design",
    "rare": "rare",
    "mission": "mission",
}


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line on stderr (then exit 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _module(command: str) -> Any:
    """The module that declares and runs ``command`` (those of ``tune``, ``linearize``,
    ``rare`` and ``mission`` are first imported when the parser is built, not for
    ``--version``)."""
    return importlib.import_module(f"quadrs.cli.{_MODULES[command]}")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The ``quadrs`` argument parser with every subcommand, or with subcommand ``only`` alone
    (what ``main`` builds when the command line names one: the other commands' modules, and
    the libraries their choices come from, are then not imported; a second on a cold start)."""
    common = scenario_options()
    parser = Parser(
        prog="quadrs",
        description="A quadrotor with a spring-attached or cable-slung payload through "
        "turbulence, wind and gusts: single flights, paired Monte Carlo batches, sweeps, "
        "stability and tuning, mission risk along a route, rare events and the paper's "
        "figures. Units are SI (m, s, kg, N; angles in scenario keys in rad; frequencies in "
        "Hz), but degrees for headings (wind.heading), swing (every table and figure, --limit, "
        "tune --constraint, rare --threshold) and PX4's angles and rates "
        "([controller.px4], as PX4 states them). Default controller: run and tune fly smc "
        "(the paper's proposed law, the paper preset's subject), mission and rare pd (the law "
        "the delivery preset is tuned for and its documented answers use), mc, stability and "
        "linearize both (paired); --controller picks another.",
        epilog="Exit status: 0 success; 1 an output could not be written (the results go to a "
        "recovery file), stability found an unstable closed loop, or tune found no admissible "
        "or feasible candidate; 2 bad input (one line on stderr); 130 Ctrl-C, 143 SIGTERM "
        "(what finished is saved).",
    )
    from quadrs._core import __version__

    parser.add_argument("--version", action="version", version=f"quadrs {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in [only] if only in _MODULES else _MODULES:
        add = getattr(_module(command), f"add_{command}")
        if command == "report":  # a saved file: no scenario options
            add(sub)
        elif command == "mission":  # its own default preset, named in its help
            from quadrs.cli.mission import DEFAULT_PRESET

            add(sub, scenario_options(DEFAULT_PRESET))
        else:
            add(sub, common)
    return parser


def _runner(command: str) -> Callable[[argparse.Namespace], int]:
    """What runs ``command``: its module's ``cmd_<command>``, looked up when it runs."""

    def run(args: argparse.Namespace) -> int:
        return int(getattr(_module(command), f"cmd_{command}")(args))

    return run


#: Each subcommand -> the function that runs it with the parsed arguments (its exit status).
COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {c: _runner(c) for c in _MODULES}


# -- entry point ------------------------------------------------------------------------------
@contextlib.contextmanager
def _terse_warnings() -> Iterator[None]:
    """Warnings as one ``quadrs: warning: ...`` line each, without source lines, each distinct
    message once (a sweep would otherwise repeat the same stability warning at every point)."""
    seen: set[str] = set()

    def show(message: Warning | str, category: type[Warning], *_: Any, **__: Any) -> None:
        text = one_line(str(message))
        if text not in seen:
            seen.add(text)
            kind = "note" if category.__name__ == "StabilityNote" else "warning"  # calm: harmless
            note(f"quadrs: {kind}: {text}")

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield


def _bad_input_types() -> tuple[type[BaseException], ...]:
    """What counts as bad input: scenario errors (a ValueError), other ValueErrors from the
    API (which include pyarrow's ArrowInvalid) and files that cannot be read."""
    return (ValueError, OSError, MemoryError)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``quadrs`` with ``argv`` (default: the process's arguments); returns the exit
    status (the console script exits with it)."""
    if list(sys.argv[1:] if argv is None else argv) == ["--version"]:
        # answered before the parser is built: its choices come from modules that load
        # pandas and the design loop (seconds on a cold start)
        from quadrs._core import __version__

        print(f"quadrs {__version__}")
        return EXIT_OK
    try:
        # building the parser imports the libraries its choices come from (a second or two
        # on a cold start): a Ctrl-C meanwhile is an interruption, not a traceback
        args_list = list(sys.argv[1:] if argv is None else argv)
        parser = build_parser(args_list[0] if args_list else None)
        args = parser.parse_args(args_list)
    except SystemExit as e:  # --help, --version or a usage error
        return int(e.code) if isinstance(e.code, int) else EXIT_USAGE
    except KeyboardInterrupt:
        print("quadrs: interrupted", file=sys.stderr)
        return EXIT_INTERRUPT
    prog = f"quadrs {args.command}"
    terminated: list[int] = []
    # The console command with a cluster: a signal while Dask closes at exit ends it as an
    # interruption, not a traceback (ExitAfterDask); registered before Dask is imported.
    at_exit = argv is None and getattr(args, "scheduler", None) is not None
    if at_exit:
        exit_after_dask.register()
    try:
        return _run(args, prog, terminated)
    finally:
        if at_exit:
            exit_after_dask.hold()


def _run(args: argparse.Namespace, prog: str, terminated: list[int]) -> int:
    """The command of ``args``, its exit status; bad input one line (status 2), Ctrl-C 130."""
    try:
        with _terse_warnings(), _sigterm_as_interrupt(terminated):
            status = COMMANDS[args.command](args)
        return EXIT_TERMINATED if terminated and status == EXIT_INTERRUPT else status
    except KeyboardInterrupt:
        print(f"{prog}: {'terminated' if terminated else 'interrupted'}", file=sys.stderr)
        return EXIT_TERMINATED if terminated else EXIT_INTERRUPT
    except _bad_input_types() as e:
        if os.environ.get("QUADRS_TRACEBACK"):
            raise
        print(terminal_text(f"{prog}: error: {_describe(e)}"), file=sys.stderr)
        return EXIT_USAGE


@contextlib.contextmanager
def _sigterm_as_interrupt(terminated: list[int]) -> Iterator[None]:
    """SIGTERM handled like Ctrl-C (cancel, save what finished), noted in ``terminated`` so
    that the exit status is 143. Only on the main thread, and not where SIGTERM is ignored; the
    old handler is restored."""
    import signal
    import threading

    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGTERM) == signal.SIG_IGN
    ):
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        terminated.append(signum)
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _describe(e: BaseException) -> str:
    if isinstance(e, OSError) and e.filename is not None:
        return f"{e.filename!r}: {e.strerror or e}"
    return one_line(str(e)) or type(e).__name__


if __name__ == "__main__":
    sys.exit(main())
