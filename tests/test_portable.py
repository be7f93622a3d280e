"""What a run and its log hold is the same bits on every machine, not only what the compiled step
computes (tests/test_determinism.py compiles it for a generic CPU): the set-up and the log's own
numbers used libm and numpy's ``@`` (log format 5), whose last bits depend on the machine. glibc
picks its cos, sin, tan, acos and pow by CPU (with fused multiply-adds on AVX2 machines), and
OpenBLAS its dot-product kernel. Here each is computed in subprocesses made into an older machine
(GLIBC_TUNABLES without AVX2 and FMA, OPENBLAS_CORETYPE=Prescott) and compared with this one's, bit
for bit: the body's turn each tick, a sloped, spinning scene's run, an event's tilt, the stable
sub-step of each method. Each comparison is shown able to fail: libm's own cos, and format 5's tilt,
differ between the two."""
from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from touchdown.logs.header import tilt_deg

ROOT = Path(__file__).resolve().parents[1]

#: in each subprocess, as hex floats: the tilt of 400 random ships as format 6 and as format 5 made
#: it; the largest stable step of each explicit method at several dampings; the body's turn at
#: 20,000 ticks and libm's cosine of the same angles; a digest of a short run on a spinning body
#: and a slope with ships at headings, tilts and yaws
_SCRIPT = """
import hashlib, math, numpy as np
from touchdown.logs import header as H
from touchdown.sim.frames import body_rotation
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
from touchdown.sim.state import State, STATE_DTYPE
from touchdown.sim.stability import largest_stable_wh
rng = np.random.default_rng(7)
rows = np.zeros(400, STATE_DTYPE)
rows["pos_m"] = rng.standard_normal((400, 3)) * 1.7e6
q = rng.standard_normal((400, 4))
rows["quat"] = q / np.linalg.norm(q, axis=1)[:, None]
st = State(rows=rows, tick=0)
for fmt in (6, 5):
    print(fmt, " ".join(H.ship_state_message("s", "p", "Luna", st, i, log_format=fmt).tilt_deg.hex()
                        for i in range(400)))
print("wh", " ".join(largest_stable_wh(m, z).hex() for m in
      ("explicit_euler", "semi_implicit_euler", "velocity_verlet", "rk4")
      for z in (0.0, 0.1, 0.3, 0.5, 0.7)))
om = 2.0 * math.pi / 3600.0
print("turn", " ".join(c.hex() + s.hex() for c, s in (body_rotation(om, k * 0.37)
                                                        for k in range(20000))))
print("libm", " ".join(math.cos(om * k * 0.37).hex() for k in range(20000)))
doc = {"name": "portable", "duration": 0.6, "body": {"rotation_period": 86400.0,
       "terrain": {"slope_deg": 17.0, "slope_azimuth_deg": 33.0}},
       "ships": [{"id": f"s{i}", "initial": {"altitude": 0.05 + 0.1 * i, "vertical_speed": -2.0,
                  "horizontal_speed": 1.0 + i, "heading_deg": 17.0 * i + 3.0,
                  "tilt_deg": 4.0 * i + 1.0, "yaw_deg": 29.0 * i + 7.0,
                  "east": 11.0 * i, "north": -7.0 * i}} for i in range(6)]}
h = hashlib.sha256()
for rec in run(parse(doc, "portable")):
    for name in rec.state.rows.dtype.names:
        h.update(np.ascontiguousarray(rec.state.rows[name]).tobytes())
print("run", h.hexdigest())
"""

#: an older machine: glibc's cos, sin, pow, ... without AVX2 and FMA; OpenBLAS's SSE3 kernels
OLDER = {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA", "OPENBLAS_CORETYPE": "Prescott"}


def _under(**env: str) -> dict[str, str]:
    r = subprocess.run([sys.executable, "-c", _SCRIPT], env=dict(os.environ, **env), cwd=ROOT,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return dict(line.split(" ", 1) for line in r.stdout.splitlines())


def test_a_run_and_its_events_are_the_same_bits_on_an_older_machine():
    here, older = _under(), _under(**OLDER)
    for what in ("6", "wh", "turn", "run"):
        assert here[what] == older[what], what
    # the comparisons can fail: libm's cosine and format 5's tilt (OpenBLAS's dot product and
    # libm's pow and acos) differ between the two (glibc 2.36: 254 of 400,000 random cosines;
    # OpenBLAS 0.3.31: a sixth of random dot products)
    assert here["libm"] != older["libm"]
    assert here["5"] != older["5"]


def _tilted(theta_rad: float, p: np.ndarray, axis_seed: int) -> tuple[tuple, tuple]:
    """A ship at p whose long axis is tilted theta from p / |p|: the attitude turning the body z
    onto r_hat, then a turn of theta about a horizontal axis."""
    # the axis's numbers from a stream of their own: drawn from default_rng(axis_seed) alone they
    # were, for k = 0 at theta 1e-7 deg (whose positions come from default_rng(0) too), p's own
    # direction, the cross product rounding only, and the "horizontal" axis whatever that
    # rounding was on the machine (mostly vertical on an Intel Xeon: a tilt of 2.7e-8 deg built)
    rng = np.random.default_rng((axis_seed, 1))
    r_hat = p / np.linalg.norm(p)
    side = np.cross(r_hat, rng.standard_normal(3))
    assert np.linalg.norm(side) > 1e-3, "an axis nearly along r_hat: not horizontal once rounded"
    side /= np.linalg.norm(side)
    # body z onto r_hat: about z x r_hat by acos(r_hat_z)
    ax = np.cross((0.0, 0.0, 1.0), r_hat)
    s = np.linalg.norm(ax)
    a = math.atan2(s, r_hat[2])
    q1 = np.concatenate(([math.cos(a / 2)], math.sin(a / 2) * ax / s))
    q2 = np.concatenate(([math.cos(theta_rad / 2)], math.sin(theta_rad / 2) * side))
    w1, v1, w2, v2 = q1[0], q1[1:], q2[0], q2[1:]  # q2 (x) q1: first q1, then q2
    q = np.concatenate(([w2 * w1 - v2 @ v1], w2 * v1 + w1 * v2 + np.cross(v2, v1)))
    return tuple(p.tolist()), tuple(q.tolist())


@pytest.mark.parametrize("theta_deg", [0.0, 1e-7, 1e-3, 0.5, 5.0, 37.0, 90.0, 135.0, 179.9])
def test_an_events_tilt_is_the_constructed_tilt(theta_deg):
    """Against the closed form: a ship built tilted theta reads theta, to 1e-9 deg at every
    angle, small ones included (acos of the dot product, format 5's way, reads 1e-7 deg as
    0 or 1.2e-6: its argument's rounding is 1e-16 of 1 - theta^2 / 2)."""
    rng = np.random.default_rng(int(theta_deg * 1000))
    for k in range(20):
        p = rng.standard_normal(3) * 1.7e6
        pos, quat = _tilted(math.radians(theta_deg), p, k)
        assert tilt_deg(pos, quat) == pytest.approx(theta_deg, abs=1e-9, rel=1e-12)


@pytest.mark.parametrize("span", [4.0, 1e4, 1e6])
def test_trig_is_within_three_ulp_of_libm(span):
    """sim.trig's cos and sin against libm's (within an ulp of the true values) over 20,000
    random angles in [-span, span] rad, and exactly libm's at the quarter turns."""
    from touchdown.sim import trig
    rng = np.random.default_rng(int(span))
    for x in rng.uniform(-span, span, 20000).tolist():
        c, s = trig.cos_sin(x)
        assert abs(c - math.cos(x)) <= 3 * math.ulp(math.cos(x)), x
        assert abs(s - math.sin(x)) <= 3 * math.ulp(math.sin(x)), x
        assert trig.tan(x) == pytest.approx(math.tan(x), rel=1e-14, abs=1e-300)
    for k in range(-8, 9):
        x = k * math.pi / 2
        assert trig.cos_sin(x) == (math.cos(x), math.sin(x)), k
    assert trig.cos_sin(-0.0) == (1.0, -0.0) and math.copysign(1.0, trig.sin(-0.0)) == -1.0
