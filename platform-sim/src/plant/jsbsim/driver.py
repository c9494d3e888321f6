"""JSBSim in lock-step for skyframe's simulator (platform-sim/src/plant/jsbsim/mod.rs).

Started as `python3 -u -c <this file> AIRCRAFT_DIR`; talks on stdin/stdout:
  1. one JSON line in: {"aircraft", "root" (null: the package's own), "dt_s", "lat_deg",
     "lon_deg", "ground_msl_m", "initial": {"kind": "runway"|"flight", "heading_deg",
     "altitude_m", "airspeed_mps"}};
     one JSON line out: {"ok": true, "version", "trim": [aileron, elevator, rudder, throttle]}
     (our sign conventions), or {"error": "..."} and exit 1.
  2. then frames: 9 little-endian f64 in (aileron, elevator, rudder, throttle, brake in our
     conventions; wind north, east, down m/s; frames to run), OUT_FIELDS f64 out.
Units are converted here only where JSBSim has no SI property; the Rust side converts the rest
and its tests check the result against physics.
"""
import json
import os
import struct
import sys

FT = 0.3048

# JSBSim's C++ side prints banners and notes on standard output, which is our channel: keep a
# private copy of it for the protocol and send fd 1 (and everything printed there) to stderr.
_PROTOCOL_FD = os.dup(1)
os.dup2(2, 1)
PROTOCOL = os.fdopen(_PROTOCOL_FD, "wb", buffering=0)

def fail(message):
    PROTOCOL.write((json.dumps({"error": message}) + "\n").encode())
    sys.exit(1)

try:
    import jsbsim
except Exception as e:  # noqa: BLE001 - any import failure is reported the same way
    fail(f"the jsbsim Python package is not installed ({e}); pip install jsbsim")

IN = struct.Struct("<9d")
# What JSBSim reports each frame, in this order (mod.rs: Frame::from_values).
OUT_PROPS = [
    "position/lat-geod-deg",
    "position/long-gc-deg",
    "position/h-agl-ft",
    "velocities/v-north-fps",
    "velocities/v-east-fps",
    "velocities/v-down-fps",
    "velocities/u-fps",
    "velocities/v-fps",
    "velocities/w-fps",
    "attitude/phi-rad",
    "attitude/theta-rad",
    "attitude/psi-rad",
    "velocities/p-rad_sec",
    "velocities/q-rad_sec",
    "velocities/r-rad_sec",
    # Every force but gravity (aero, propulsion, ground), body axes: over the mass this is
    # what an accelerometer at the CG reads.
    "forces/fbx-total-lbs",
    "forces/fby-total-lbs",
    "forces/fbz-total-lbs",
    "inertia/mass-slugs",
    "velocities/vt-fps",
    "aero/alpha-rad",
    "aero/beta-rad",
    "atmosphere/total-wind-north-fps",
    "atmosphere/total-wind-east-fps",
    "atmosphere/total-wind-down-fps",
    "propulsion/engine/thrust-lbs",
    "propulsion/engine/engine-rpm",
    "gear/wow",
    "simulation/sim-time-sec",
]
OUT = struct.Struct("<%dd" % len(OUT_PROPS))


def main():
    line = sys.stdin.readline()
    if not line:
        sys.exit(0)
    try:
        cfg = json.loads(line)
    except ValueError as e:
        fail(f"bad start message: {e}")
    fdm = jsbsim.FGFDMExec(cfg.get("root"))
    fdm.set_debug_level(0)
    try:
        loaded = fdm.load_model(cfg["aircraft"])
    except Exception as e:  # noqa: BLE001 - JSBSim raises several kinds
        loaded = False
    if not loaded:
        fail(f"JSBSim has no aircraft \"{cfg['aircraft']}\" (in {fdm.get_root_dir()})")
    fdm.set_dt(cfg["dt_s"])
    init = cfg["initial"]
    fdm["ic/lat-geod-deg"] = cfg["lat_deg"]
    fdm["ic/long-gc-deg"] = cfg["lon_deg"]
    fdm["ic/terrain-elevation-ft"] = cfg["ground_msl_m"] / FT
    fdm["ic/psi-true-deg"] = init["heading_deg"]
    flying = init["kind"] == "flight"
    if flying:
        fdm["ic/h-agl-ft"] = init["altitude_m"] / FT
        fdm["ic/vt-fps"] = init["airspeed_mps"] / FT
    else:
        fdm["ic/h-agl-ft"] = 0.0
        fdm["ic/vt-fps"] = 0.0
    if not fdm.run_ic():
        fail("JSBSim refused the initial conditions")
    fdm["propulsion/set-running"] = -1
    fdm["fcs/mixture-cmd-norm"] = 1.0
    trim = [0.0, 0.0, 0.0, 0.0]
    if flying:
        fdm["fcs/throttle-cmd-norm"] = 0.6
        try:
            fdm.do_trim(1)
        except Exception as e:  # noqa: BLE001
            fail(f"JSBSim cannot trim {cfg['aircraft']} at {init['airspeed_mps']} m/s: {e}")
        # The trim lands in the pitch-trim wheel; move it onto the elevator, which is what
        # skyframe commands, so the first command (the trim) keeps the airplane trimmed.
        pitch = fdm["fcs/pitch-trim-cmd-norm"] + fdm["fcs/elevator-cmd-norm"]
        fdm["fcs/pitch-trim-cmd-norm"] = 0.0
        fdm["fcs/elevator-cmd-norm"] = pitch
        # JSBSim: positive elevator pitches down and positive rudder yaws left.
        trim = [
            fdm["fcs/aileron-cmd-norm"],
            -pitch,
            -fdm["fcs/rudder-cmd-norm"],
            fdm["fcs/throttle-cmd-norm"],
        ]
    out = PROTOCOL
    hello = {"ok": True, "version": jsbsim.__version__, "trim": trim}
    out.write((json.dumps(hello) + "\n").encode())
    inp = sys.stdin.buffer
    props = [fdm.get_property_manager().get_node(p, False) for p in OUT_PROPS]
    missing = [p for p, n in zip(OUT_PROPS, props) if n is None]
    if missing:
        fail(f"{cfg['aircraft']} has no properties {', '.join(missing)}")
    while True:
        data = inp.read(IN.size)
        if len(data) < IN.size:
            return
        ail, ele, rud, thr, brake, wn, we, wd, frames = IN.unpack(data)
        fdm["fcs/aileron-cmd-norm"] = ail
        fdm["fcs/elevator-cmd-norm"] = -ele
        fdm["fcs/rudder-cmd-norm"] = -rud
        fdm["fcs/throttle-cmd-norm"] = thr
        fdm["fcs/left-brake-cmd-norm"] = brake
        fdm["fcs/right-brake-cmd-norm"] = brake
        fdm["atmosphere/wind-north-fps"] = wn / FT
        fdm["atmosphere/wind-east-fps"] = we / FT
        fdm["atmosphere/wind-down-fps"] = wd / FT
        for _ in range(int(frames)):
            if not fdm.run():
                fail("JSBSim stopped")
        out.write(OUT.pack(*[n.get_double_value() for n in props]))


main()
