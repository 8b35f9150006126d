"""report.md's check of the paper's claims: verdicts from the CI of P = 100 SMC/PD."""

import pandas as pd

from quadrs.paper.pipeline import claims


def summary(rows: list[tuple[str, str, float, float, float]]) -> pd.DataFrame:
    frame = pd.DataFrame(rows, columns=["metric", "phase", "P", "P_ci_low", "P_ci_high"])
    return frame.set_index(["metric", "phase"])


def test_claims_read_the_interval_not_the_point() -> None:
    table = claims(
        summary(
            [
                ("iae", "P1", 60.0, 55.0, 65.0),  # below 100: the paper's claim holds
                ("max_abs", "P1", 123.0, 120.0, 126.0),  # above: contradicted
                ("max_abs", "P2", 95.0, 80.0, 110.0),  # straddles: undecided
                ("rms", "P1", 105.0, 105.0, 105.0),  # no gust: one exact value, above
            ]
        )
    )
    assert table["ours"].tolist() == [
        "SMC lower",
        "SMC higher",
        "no clear difference",
        "SMC higher",
    ]
    assert table["agrees"].tolist() == ["yes", "NO", "undecided", "NO"]


def test_claims_keep_the_sweep_key() -> None:
    s = summary([("max_abs", "P1", 130.0, 120.0, 140.0), ("max_abs", "P3", 90.0, 85.0, 95.0)])
    s = pd.concat({2.0: s, 4.0: s}, names=["payload.natural_frequency"])
    table = claims(s)
    assert table["payload.natural_frequency"].tolist() == [2.0, 2.0, 4.0, 4.0]
    assert table["agrees"].tolist() == ["NO", "yes", "NO", "yes"]
