"""workload.py ROW N (ROW=quiet: $QUIET_LIST's ticks, N copies each, see session19-settle): bench/states.py's row ROW (N ships, 40 ticks at dt 0.05), or ROW=env: the
first N of bench/states.py's 300 envelope touchdowns (the sweep's loop). Runs it once warm
(compiles or loads, symbol map written to $KPROF_OUT), then again with callgrind's
instrumentation on (when under callgrind). Run from the measured tree's root (PYTHONPATH)."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import symmap  # noqa: E402

symmap.install()
row, n = sys.argv[1], int(sys.argv[2])
if row == "quiet":
    # the envelope touchdowns' quiet contact ticks (no foot sliding) restarted from their recorded
    # states, N copies each (session19-settle/quiet_ticks.py; $QUIET_LIST, $QUIET_PATHS)
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..",
                                    "session19-settle"))
    import json
    import quiet_ticks
    _paths = os.environ.get("QUIET_PATHS", "all")
    _items = quiet_ticks.ticks(json.load(open(os.environ["QUIET_LIST"])),
                               None if _paths == "all" else _paths.split(","), n)
    print("quiet ship-ticks", len(_items) * n, flush=True)

    def work():
        quiet_ticks.work(_items)
elif row == "env":
    import tomllib
    from touchdown import scenarios
    from touchdown.sweep.cases import Axis, Sweep
    from touchdown.sweep.fleet import run_part
    doc = tomllib.loads(scenarios.text("envelope"))
    axes = [Axis("ships.initial.vertical_speed", -12.0, -1.0),
            Axis("ships.initial.horizontal_speed", 0.0, 6.0),
            Axis("ships.initial.tilt_deg", 0.0, 15.0)]
    # $KPROF_SIM (KEY=VALUE,...): sim settings over the envelope's (a setting's variants, one tree)
    def _value(text):  # a number, else a word (sim.integrator's)
        try:
            return float(text)
        except ValueError:
            return text
    doc.setdefault("sim", {}).update({kv.split("=", 1)[0]: _value(kv.split("=", 1)[1]) for kv
                                      in os.environ.get("KPROF_SIM", "").split(",") if kv})
    sw = Sweep.of(doc, "envelope", axes, samples=300, seed=1)

    def work():
        run_part(sw, list(range(n)))
else:
    sys.path.insert(0, os.path.join(os.getcwd(), "bench"))
    import states
    from touchdown.sim.run import run_blocks
    from touchdown.sim.scenario import parse
    _label, ini, inputs = states.SCENES[int(row)]

    # parsed once, outside the instrumented run (bench/states.py times run_blocks alone)
    scn = parse({"name": "cost", "duration": 40 * 0.05,
                 "ships": states.ships_in_state(ini, inputs, n), "sim": {"dt": 0.05}}, "bench")

    def work():
        for _b in run_blocks(scn):
            pass
work()
if os.environ.get("KPROF_OUT"):
    symmap.write(os.environ["KPROF_OUT"])
symmap.callgrind(True)
work()
symmap.callgrind(False)
