"""``quadrs run``: fly the scenario once and print the per-phase metrics; optionally its
figures and its time trace."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from quadrs.cli.common import EXIT_FAIL, EXIT_OK, controller_option, path_option, seed_option

__all__ = ["add_run", "cmd_run"]


def add_run(sub: Any, common: argparse.ArgumentParser) -> None:
    p = sub.add_parser(
        "run",
        parents=[common],
        help="fly once and print the per-phase metrics",
        description="Fly the scenario once and print the per-phase metrics of the relative "
        "oscillation e_o (IAE in m s, ITAE in m s^2, max_abs/rms in m, tracking_rms in m, "
        "peak_frequency in Hz, peak_amplitude in m) and of the payload's vertical "
        "acceleration (max_accel, rms_accel in m/s^2).",
    )
    controller_option(p)
    seed_option(p)
    p.add_argument(
        "--realisation",
        type=int,
        default=0,
        metavar="I",
        help="gust realisation of the seed, the same as realisation I of `quadrs mc` (default: 0)",
    )
    path_option(p, "--plot", "DIR", "write the flight's figures here")
    path_option(
        p,
        "--trace",
        "FILE",
        "write the time trace (t in s; states, references, controls, wind in m/s, e_o in m) "
        "as .parquet (with the scenario, seed, controller, realisation and version; read it "
        "with quadrs.Flight.read_parquet) or plain .csv",
    )


def cmd_run(args: argparse.Namespace) -> int:
    """One flight: metrics table, optional figures and trace."""
    from quadrs import plots
    from quadrs.cli.outputs import check_directories, check_outputs, check_suffix, save
    from quadrs.cli.scenario_args import load_scenario
    from quadrs.cli.tables import print_frame
    from quadrs.runs.flight import simulate

    scenario = load_scenario(args)
    check_suffix(args.trace, (".parquet", ".csv"), "--trace")
    check_outputs(args.trace)
    check_directories(args.plot, option="--plot")
    flight = simulate(scenario, args.controller, args.seed, realisation=args.realisation)
    print(f"{args.controller.upper()}, seed {args.seed}, realisation {args.realisation}")
    print_frame(flight.metrics.set_index("phase"))
    if flight.diverged:
        print(f"warning: the flight diverged at t = {flight.diverged_at:g} s", file=sys.stderr)
    status = EXIT_OK

    def write_trace(path: Path) -> None:
        if path.suffix.lower() == ".csv":
            flight.to_csv(path)
        else:
            flight.to_parquet(path)

    if args.trace is not None and not save(write_trace, args.trace):
        status = EXIT_FAIL
    if args.plot is not None:
        from quadrs.cli.figures import write_figures

        write_figures(
            [
                ("altitude", lambda: plots.altitude(flight)),
                ("oscillation", lambda: plots.oscillation(flight)),
                ("spectra", lambda: plots.spectra(flight)),
                ("psd", lambda: plots.psd(flight)),
                ("gust_force", lambda: plots.gust_force(flight)),
            ],
            args.plot,
        )
    return status
