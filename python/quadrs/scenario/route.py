"""A route's schedule as Python sees it (``Scenario.route``; docs/model.md, "Routes").

The engine computes the schedule (rust/src/config/route.rs): one segment per hold and leg, in time
order, covering the flight. Under ``phases = "legs"`` each segment is a phase of that name.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

#: The whole-flight phase every result has after the scenario's own phases.
FLIGHT_PHASE = "flight"

Point = tuple[float, float, float]


@dataclass(frozen=True)
class RouteSegment:
    """One hold, leg or lowering of a route. Times in s from the start of the flight, lengths
    in m."""

    name: str
    #: A lowering hovers at its point while the winch pays out ``payout`` m of line.
    kind: Literal["hold", "leg", "lower"]
    #: When the segment begins (a leg leaves ``origin`` at rest).
    start: float
    #: When the reference is at rest at ``target`` (a hold: ``start``).
    arrival: float
    #: When the next segment begins (the end of the flight for the last one).
    end: float
    origin: Point
    target: Point
    #: Straight-line length (0 for a hold).
    length: float
    #: m/s, the highest reference speed on the leg: the cruise speed, or less on a leg too
    #: short to reach it.
    peak_speed: float
    #: s, each of the leg's two acceleration ramps.
    ramp: float
    #: s, at peak speed between the ramps.
    cruise: float
    #: m, the line a lowering pays out beyond ``payload.length_min`` (0 for a hold or leg).
    payout: float = 0.0


@dataclass(frozen=True)
class Route:
    """The holds and legs of a route in time order."""

    segments: tuple[RouteSegment, ...]

    @classmethod
    def from_engine(cls, rows: Iterable[Mapping[str, Any]]) -> Route:
        """From the engine's description (``_core.describe(...)["route"]``)."""
        segments = []
        for r in rows:
            values = dict(r)
            values["origin"] = tuple(float(x) for x in values["origin"])
            values["target"] = tuple(float(x) for x in values["target"])
            segments.append(RouteSegment(**values))
        return cls(tuple(segments))

    @property
    def legs(self) -> list[RouteSegment]:
        return [s for s in self.segments if s.kind == "leg"]

    @property
    def lowerings(self) -> list[RouteSegment]:
        """The segments that lower the parcel (``trajectory.lower``)."""
        return [s for s in self.segments if s.kind == "lower"]

    @property
    def arrival(self) -> float:
        """s, when the reference comes to rest at the last point."""
        return self.legs[-1].arrival

    @property
    def length(self) -> float:
        """m, the sum of the legs' lengths."""
        return sum(s.length for s in self.legs)

    def table(self) -> pd.DataFrame:
        """One row per segment, indexed by name."""
        import pandas as pd

        return pd.DataFrame([asdict(s) for s in self.segments]).set_index("name")
