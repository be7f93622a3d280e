"""What leaner tick records would cost: the encoder with some fields moved to keyframes only
(BlockEncoder's keyframe_only), then zstd, on bench/mujoco_side.py's fleet's ticks 1-20."""
import time, numpy as np, zstandard, zlib
from touchdown.bench.fleet_log_parts import fleet_scenario
from touchdown.sim.run import run_blocks
from touchdown.logs.encode_block import BlockEncoder
from touchdown.logs.header import KEYFRAME_ONLY
scn = fleet_scenario(10000, 20)
blocks = list(run_blocks(scn))[1:]
keys = np.arange(10000, dtype=np.int64)
N = 10000 * len(blocks)
INPUTS = ("input_throttle", "input_rcs", "input_hold")
OUT_ALL = ("altitude_m", "penetration_m", "peak_penetration_m", "cos_tilt", "v_radial_mps",
           "v_tangential_mps", "normal_force_n", "friction_force_n", "throttle",
           "rcs_torque_body_nm", "energy_guard_j")
variants = {
    "format 6 (today)": (),
    "- inputs, penetration (lossless: commands, -altitude)": INPUTS + ("penetration_m",),
    "- inputs, derivable outputs (cos_tilt, v_*, penetration)": INPUTS + ("penetration_m", "cos_tilt", "v_radial_mps", "v_tangential_mps", "altitude_m"),
    "state only (+ key) every tick": INPUTS + OUT_ALL,
}
for name, drop in variants.items():
    enc = BlockEncoder(0.05, KEYFRAME_ONLY + drop, 1 << 30, keyframe_phase=0)
    best = {}
    for rep in range(3):
        t = time.thread_time(); recs = []
        for b in blocks:
            d, off = enc.encode(b.first_tick, b.states, b.outputs, b.inputs, keys, heads=(2, 0, 50_000_000))
            recs.append(d[off[0]:off[-1]])
        te = time.thread_time() - t
        for lvl in (1, -3):
            c = zstandard.ZstdCompressor(level=lvl)
            t = time.thread_time(); outs = [c.compress(r) for r in recs]; tz = time.thread_time() - t
            t = time.thread_time(); [zlib.crc32(r) for r in recs]; tc = time.thread_time() - t
            k = (lvl,)
            row = (te, tz, tc, sum(map(len, outs)))
            best[k] = row if k not in best else tuple(min(a, b) for a, b in zip(best[k], row))
    raw = sum(len(r) for r in recs) / N
    for (lvl,), (te, tz, tc, nb) in best.items():
        print(f"{name:58s} raw {raw:5.0f} B  zstd {lvl:2d}: {nb / N:5.1f} B  encode {te / N * 1e9:5.0f} ns  zstd {tz / N * 1e9:5.0f} ns  crc {tc / N * 1e9:4.0f} ns")
