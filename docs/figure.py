"""Draw the README's picture from two logs (it reads MCAP, it does not simulate):

    touchdown record bounce -o /tmp/bounce.mcap
    touchdown record topple -o /tmp/topple.mcap
    python docs/figure.py /tmp/bounce.mcap /tmp/topple.mcap docs/touchdown.png

Needs matplotlib (``pip install -e '.[bench]'``).
"""
from __future__ import annotations

import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from touchdown.logs.reader import LogReader  # noqa: E402

COLOURS = {0: "#4a90d9", 1: "#e6a700", 2: "#2e9e44", 3: "#d0342c", 4: "#555555"}
NAMES = {0: "flying", 1: "contact", 2: "landed", 3: "tipped", 4: "crashed"}


def load(path):
    with LogReader(path) as r:
        rows = [(td.t_s, td.arrays["altitude_m"][0], td.arrays["cos_tilt"][0],
                 int(td.arrays["surface_state"][0])) for td in r.ticks()]
    t, alt, cos_tilt, state = (np.array(x) for x in zip(*rows))
    return t, alt, np.degrees(np.arccos(np.clip(cos_tilt, -1, 1))), state


def coloured(ax, t, y, state):
    for s, c in COLOURS.items():
        m = np.ma.masked_where(state != s, y)
        if (state == s).any():
            ax.plot(t, m, color=c, lw=2.2, label=NAMES[s])


def main(bounce, topple, out):
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 3.6), dpi=110)
    t, alt, _, st = load(bounce)
    coloured(a1, t, alt, st)
    a1.set_title("bounce: 20 m/s onto the Moon")
    a1.set_xlabel("time (s)")
    a1.set_ylabel("lowest foot above ground (m)")
    a1.set_xlim(0, 16)
    a1.legend(loc="upper right", frameon=False)
    t, _, tilt, st = load(topple)
    coloured(a2, t, tilt, st)
    crit = math.degrees(math.atan2(2.26, 3.0))
    a2.axhline(crit, color="grey", ls=":", lw=1)
    a2.text(0.2, crit + 2, f"critical {crit:.1f} deg toward a foot = atan(leg radius / CoM height)", fontsize=8)
    a2.axhline(80, color="grey", ls="--", lw=1)
    a2.text(0.2, 82, "tipped at 80 deg", fontsize=8)
    a2.set_title("topple: touching down tilted 42 deg")
    a2.set_xlabel("time (s)")
    a2.set_ylabel("tilt (deg)")
    a2.set_ylim(0, 95)
    a2.legend(loc="lower right", frameon=False)
    fig.tight_layout()
    fig.savefig(out)


if __name__ == "__main__":
    main(*sys.argv[1:4])
