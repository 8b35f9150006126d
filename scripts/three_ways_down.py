"""docs/delivery.md, "Three ways down": the delivery preset's parcel lowered at the winch's
speed, lowered with the final approach, and dropped, in its mean wind without turbulence; the
parcel's height against time from the arrival over the drop point (the figure) and each
touchdown's metrics (printed).

    python scripts/three_ways_down.py docs/figures/three_ways_down.png
"""

import sys
import warnings

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

import quadrs

G = 9.81
base = quadrs.Scenario.preset("delivery").override({"gust.enabled": False})
NAMES = ["lift", "climb", "transit", "descent", "drop", "departure", "away"]
ways = {
    "lowered at the winch's 1 m/s": base.override(
        {"payload.approach_height": None, "payload.approach_speed": None}
    ),
    "lowered with the final approach (0.3 m/s below 2 m)": base,
    "dropped on arrival ({ height = 4.0 })": base.override(
        {
            "trajectory.lower": [0.0] * 5,
            "payload.release": {"height": 4.0},
            "trajectory.hold": [2.0, 0.0, 0.0, 10.0, 0.0],
            "trajectory.names": NAMES,
        }
    ),
}
fig, ax = plt.subplots(figsize=(7, 3.6))
for name, sc in ways.items():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = quadrs.simulate(sc, "pd", record_every=10)
    m = f.metrics.set_index("phase").loc["flight"]
    (descent,) = [s for s in sc.route.legs if s.name == "descent"]
    t0 = descent.arrival
    tr = f.trace
    win = tr[(tr.index > t0 - 3) & (tr.index < t0 + 12)]
    ax.plot(win.index - t0, win["zc"], label=name)
    print(
        f"{name}: touchdown {m['touchdown_speed']:.3f} m/s, drop height "
        f"{m['touchdown_drop_height'] * 1000:.1f} mm, peak {m['touchdown_peak_force']:.1f} m/s^2 "
        f"({m['touchdown_peak_force'] / G:.1f} g), drift {m['touchdown_drift']:.3f} m/s, "
        f"miss {m['touchdown_miss']:.2f} m, released at {m['release_time'] - t0:.2f} s"
    )
ax.axhline(0.0, color="k", lw=0.8)
ax.set_xlabel("s after arriving over the drop point")
ax.set_ylabel("parcel's height (m)")
ax.legend(fontsize=8)
ax.set_title("Three ways down (delivery preset, mean wind, no turbulence)", fontsize=9)
fig.tight_layout()
fig.savefig(sys.argv[1], dpi=110)
