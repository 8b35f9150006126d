"""A mission's answer (:class:`quadrs.design.mission.MissionReport`) as text: its tables
formatted for a terminal or a notebook, numbers with their intervals, a count that is zero as
"0 of N flights, P <= x %", and wide tables split into blocks of columns."""

from __future__ import annotations

import math
from typing import Protocol

import pandas as pd

from quadrs.design.mission_tables import ANY_PHASE, LOWS, PEAKS, none_seen_bound


def _last_metres_text(t: pd.DataFrame, qp: str) -> pd.DataFrame:
    deg = 180 / math.pi
    return pd.DataFrame(
        {
            "runs": t["n"].astype(int),
            "touched": t["touchdowns"].astype(int),
            "P fast %": [
                _count_or_interval(
                    int(r.exceedances), int(r.judged), r.probability, r.ci_low, r.ci_high
                )
                if r.judged
                else ""
                for r in t.itertuples()
            ],
            f"speed {qp}": [
                _interval(r.speed_q, r.speed_q_low, r.speed_q_high) for r in t.itertuples()
            ],
            "speed worst": [_g(v) for v in t["speed_worst"]],
            "drift worst": [_g(v) for v in t["drift_worst"]],
            "miss worst": [_g(v) for v in t["miss_worst"]],
            "released": t["released"].astype(int),
            "height change": [_g(v) for v in t["height_change_worst"]],
            "swing worst": [_g(deg * v) for v in t["lowering_swing_worst"]],
        },
        index=t.index,
    )


def _none_spent(n: int) -> str:
    """A time column's cell when no flight spent any time there: seconds, not a probability
    (the probability of any time spent is the count's, "0 of N flights" elsewhere)."""
    return f"0 in all {n}"


def _g(v: float, digits: int = 3) -> str:
    if isinstance(v, float) and math.isnan(v):
        return ""
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return f"{v:.{digits}g}"


def _interval(v: float, lo: float, hi: float, scale: float = 1.0, digits: int = 3) -> str:
    if math.isnan(v):
        return ""
    return f"{_g(scale * v, digits)} [{_g(scale * lo, digits)}, {_g(scale * hi, digits)}]"


def _shown_name(metric: str) -> str:
    """``acceleration (m/s^2)`` for max_accel; ``max_swing (deg)``; ``max_tension (N)``."""
    if metric == "max_accel":
        return "acceleration (m/s^2)"
    unit = _unit(metric)
    return f"{metric} ({unit})" if unit else metric


def _unit(metric: str) -> str:
    from quadrs.present.labels import shown_unit

    return shown_unit(metric).replace("²", "^2")


class _Asked(Protocol):
    """What a limit is shown from: the metric and its limit (a :class:`MissionReport`)."""

    @property
    def metric(self) -> str: ...

    @property
    def limit(self) -> float: ...


def _shown_limit(report: _Asked) -> str:
    from quadrs.present.labels import STANDARD_GRAVITY, display_scale, in_g

    shown = f"{display_scale(report.metric) * report.limit:g}"
    if in_g(report.metric):
        return f"{shown} m/s^2 ({report.limit / STANDARD_GRAVITY:.3g} g)"
    unit = _unit(report.metric)
    return f"{shown} {unit}" if unit else shown


def _pct(p: float) -> str:
    return _g(100 * float(p))


def _limits_text(track: float, cross: float) -> str:
    return f"{track:g} m" if track == cross else f"{track:g} m and {cross:g} m"


def _count_or_interval(k: int, n: int, p: float, lo: float, hi: float) -> str:
    """``0 of 200 flights, P <= 1.49`` when nothing happened, else ``p [lo, hi]`` (in %)."""
    if k == 0 and n > 0:
        return f"0 of {n} flights, P <= {_pct(none_seen_bound(n))}"
    return _interval(p, lo, hi, 100.0)


def _joint_line(joint: pd.DataFrame | None, table: str, what: str) -> str:
    if joint is None or table not in joint.index:
        return ""
    r = joint.loc[table]
    n, k = int(r["n"]), int(r["count"])
    flights = int(r.get("flights", n))
    if n == 0:
        return (f"{ANY_PHASE}: not judged: none of the {flights} flights has a value of the "
                "metric in any phase (an event metric: the event, a touchdown, never "
                "happened), so none can have exceeded it")  # fmt: skip
    unjudged = f" ({flights - n} without a value in any phase left out)" if flights > n else ""
    if k == 0:
        said = f"0 of {n} flights, P <= {_pct(r['p_max'])} % (two-sided 95 % interval)"
    else:
        said = (f"{k} of {n} flights, P = "
                f"{_interval(r['probability'], r['ci_low'], r['ci_high'], 100.0)} %")  # fmt: skip
    return f"{ANY_PHASE}: {said} {what} in at least one phase (a joint statement){unjudged}"


def _route_text(t: pd.DataFrame) -> pd.DataFrame:
    out = pd.DataFrame(
        {
            "runs": t["n"].astype(int),
            "diverged": t["diverged"].astype(int),
            "off route": t["off_route"].astype(int),
            "P off route %": [
                _count_or_interval(int(r.off_route), int(r.n), r.probability, r.ci_low, r.ci_high)
                for r in t.itertuples()
            ],
        },
        index=t.index,
    )
    for m, name in (("max_tracking", "tracking worst m"), ("max_cross_track", "cross worst m")):
        if f"{m}_worst" in t:
            out[name] = [_g(v) for v in t[f"{m}_worst"]]
    if "saturated_time_mean" in t:
        cells = []
        for r in t.itertuples():
            flights = getattr(r, "saturated_time_flights", math.nan)
            n = getattr(r, "saturated_time_n", math.nan)
            if isinstance(flights, (int, float)) and flights == 0 and n and n == n:
                cells.append(_none_spent(int(n)))
            else:
                cells.append(_interval(r.saturated_time_mean, r.saturated_time_ci_low,
                                       r.saturated_time_ci_high))  # fmt: skip
        out["at thrust limit s"] = cells
        out["thrust worst s"] = [_g(v) for v in t["saturated_time_worst"]] if (
            "saturated_time_worst" in t) else ""  # fmt: skip
    if "near_tilt_time_worst" in t:
        out["near tilt worst s"] = [_g(v) for v in t["near_tilt_time_worst"]]
    return out


def _acceleration_text(t: pd.DataFrame, qp: str, metric: str) -> pd.DataFrame:
    """The parcel's table; an acceleration's worst also in standard g (the limit's g is in
    the heading: a column more would not fit 100 columns)."""
    from quadrs.present.labels import STANDARD_GRAVITY, display_scale, in_g

    g = {"worst g": [_g(v / STANDARD_GRAVITY) for v in t["worst"]]} if in_g(metric) else {}
    scale = display_scale(metric)  # the heading's unit: degrees for swing
    return pd.DataFrame(
        {
            "runs": t["n"].astype(int),
            "diverged": t["diverged"].astype(int),
            "exceed": t["exceedances"].astype(int),
            "P exceed %": [
                _count_or_interval(int(r.exceedances), int(r.n), r.probability, r.ci_low, r.ci_high)
                for r in t.itertuples()
            ],
            qp: [_interval(r.quantile, r.q_low, r.q_high, scale) for r in t.itertuples()],
            "worst": [_g(scale * v) for v in t["worst"]],
            **g,
        },
        index=t.index,
    )


def _payload_text(t: pd.DataFrame, qp: str) -> pd.DataFrame:
    from quadrs.present.labels import display_scale

    out = pd.DataFrame(index=t.index)
    for m in PEAKS:
        if f"{m}_worst" not in t:
            continue
        scale = display_scale(m)
        name = m.removeprefix("max_")
        out[f"{name} {qp}"] = [
            _interval(a, b, c, scale)
            for a, b, c in zip(t[f"{m}_q"], t[f"{m}_q_low"], t[f"{m}_q_high"], strict=True)
        ]
        out[f"{name} worst"] = [_g(scale * v) for v in t[f"{m}_worst"]]
    for m in LOWS:
        if f"{m}_worst" in t:
            out["tension lowest"] = [_g(v) for v in t[f"{m}_worst"]]
    for m in ("slack_time",):  # the time at the thrust limit is in the route's table
        if f"{m}_mean" in t:
            out[f"{m} mean"] = [
                _none_spent(int(n)) if n == n and n > 0 and k == 0 else _interval(a, b, c)
                for a, b, c, k, n in zip(t[f"{m}_mean"], t[f"{m}_ci_low"], t[f"{m}_ci_high"],
                                         t.get(f"{m}_flights", pd.Series(math.nan, t.index)),
                                         t.get(f"{m}_n", pd.Series(math.nan, t.index)),
                                         strict=True)
            ]  # fmt: skip
    return out


def _tracking_text(t: pd.DataFrame) -> pd.DataFrame:
    out = pd.DataFrame(index=t.index)
    for col in [c for c in t.columns if c.endswith("_mean")]:
        m = col.removesuffix("_mean")
        out[f"{m} mean"] = [
            _interval(a, b, c)
            for a, b, c in zip(t[f"{m}_mean"], t[f"{m}_ci_low"], t[f"{m}_ci_high"], strict=True)
        ]
        out[f"{m} worst"] = [_g(v) for v in t[f"{m}_worst"]]
    return out
