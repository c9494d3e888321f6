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
import tempfile
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


def set_if_there(fdm, name, value):
    """Engine controls an airframe without a JSBSim engine (ours: a motor as tables) lacks."""
    if fdm.get_property_manager().get_node(name, False) is not None:
        fdm[name] = value


def set_ic(fdm, heading_deg, height_m, airspeed_mps):
    fdm["ic/psi-true-deg"] = heading_deg
    fdm["ic/h-agl-ft"] = height_m / FT
    fdm["ic/vt-fps"] = airspeed_mps / FT
    fdm["ic/gamma-deg"] = 0.0


def trimmed(fdm, cfg, heading_deg, height_m, airspeed_mps):
    """Trims level flight; returns ([aileron, elevator, rudder, throttle], pitch) in our signs,
    with the trim moved from the pitch-trim wheel onto the elevator (which is what skyframe
    commands), so the first command keeps the airplane trimmed."""
    set_ic(fdm, heading_deg, height_m, airspeed_mps)
    if not fdm.run_ic():
        fail("JSBSim refused the initial conditions")
    set_if_there(fdm, "propulsion/set-running", -1)
    set_if_there(fdm, "fcs/mixture-cmd-norm", 1.0)
    fdm["fcs/throttle-cmd-norm"] = 0.6
    try:
        fdm.do_trim(1)
    except Exception as e:  # noqa: BLE001 - JSBSim's trim failure type varies by version
        fail(f"JSBSim cannot trim {cfg['aircraft']} at {airspeed_mps} m/s: {e}")
    pitch = fdm["fcs/pitch-trim-cmd-norm"] + fdm["fcs/elevator-cmd-norm"]
    fdm["fcs/pitch-trim-cmd-norm"] = 0.0
    fdm["fcs/elevator-cmd-norm"] = pitch
    # JSBSim: positive elevator pitches down and positive rudder yaws left.
    commands = [
        fdm["fcs/aileron-cmd-norm"],
        -pitch,
        -fdm["fcs/rudder-cmd-norm"],
        fdm["fcs/throttle-cmd-norm"],
    ]
    return commands, fdm["attitude/theta-rad"]


def main():
    line = sys.stdin.readline()
    if not line:
        sys.exit(0)
    try:
        cfg = json.loads(line)
    except ValueError as e:
        fail(f"bad start message: {e}")
    # A private working directory: whatever JSBSim writes there (c172x's CSV output, opened
    # as the aircraft loads) goes with it, not into the caller's directory.
    workdir = tempfile.TemporaryDirectory(prefix="skyframe-jsbsim-")
    os.chdir(workdir.name)
    fdm = jsbsim.FGFDMExec(cfg.get("root"))
    fdm.set_debug_level(0)
    try:
        loaded = fdm.load_model(cfg["aircraft"])
    except Exception as e:  # noqa: BLE001 - JSBSim raises several kinds
        loaded = False
    if not loaded:
        fail(f"JSBSim has no aircraft \"{cfg['aircraft']}\" (in {fdm.get_root_dir()})")
    # Some aircraft (c172x) ask for CSV output files, written into the working directory as
    # the aircraft loads: ours is the pipe.
    fdm.disable_output()
    fdm.set_dt(cfg["dt_s"])
    init = cfg["initial"]
    fdm["ic/lat-geod-deg"] = cfg["lat_deg"]
    fdm["ic/long-gc-deg"] = cfg["lon_deg"]
    fdm["ic/terrain-elevation-ft"] = cfg["ground_msl_m"] / FT
    trim = None
    trim_speed = init["airspeed_mps"] if init["kind"] == "flight" else cfg.get("trim_airspeed_mps")
    given = cfg.get("given_trim")
    if given is not None and init["kind"] == "flight":
        # Someone else's trim (the built-in model's, for the cross-check on our airframe):
        # JSBSim starts from that state and those commands, and its own dynamics say whether
        # they hold.
        a, e, r, t = given["commands"]
        fdm["fcs/aileron-cmd-norm"] = a
        fdm["fcs/elevator-cmd-norm"] = -e
        fdm["fcs/rudder-cmd-norm"] = -r
        fdm["fcs/throttle-cmd-norm"] = t
        set_ic(fdm, init["heading_deg"], init["altitude_m"], init["airspeed_mps"])
        fdm["ic/alpha-rad"] = given["alpha_rad"]
        if not fdm.run_ic():
            fail("JSBSim refused the initial conditions")
        trim = ([a, e, r, t], fdm["attitude/theta-rad"])
    elif trim_speed:
        # Level flight at that speed, trimmed by JSBSim: the commands a pilot flies from.
        trim = trimmed(fdm, cfg, init["heading_deg"], max(init["altitude_m"], 100.0), trim_speed)
    t0 = 0.0
    if init["kind"] != "flight":
        # JSBSim places the CG, not the wheels: find the height where the lowest wheel just
        # touches, then let the airplane settle on its gear (brakes on, idle) before time zero.
        set_ic(fdm, init["heading_deg"], 10.0 * FT, 0.0)
        if not fdm.run_ic():
            fail("JSBSim refused the initial conditions")
        pm = fdm.get_property_manager()
        wheels = [pm.get_node(f"gear/unit[{i}]/AGL-ft", False) for i in range(int(fdm["gear/num-units"]))]
        heights = [w.get_double_value() for w in wheels if w is not None]
        lowest_ft = min(heights) if heights else 0.0
        set_ic(fdm, init["heading_deg"], (10.0 - lowest_ft) * FT + 0.01, 0.0)
        if not fdm.run_ic():
            fail("JSBSim refused the initial conditions")
        set_if_there(fdm, "propulsion/set-running", -1)
        set_if_there(fdm, "fcs/mixture-cmd-norm", 1.0)
        fdm["fcs/throttle-cmd-norm"] = 0.0
        fdm["fcs/elevator-cmd-norm"] = 0.0
        fdm["fcs/pitch-trim-cmd-norm"] = 0.0
        fdm["fcs/left-brake-cmd-norm"] = 1.0
        fdm["fcs/right-brake-cmd-norm"] = 1.0
        for _ in range(int(round(3.0 / cfg["dt_s"]))):
            fdm.run()
        t0 = fdm["simulation/sim-time-sec"]
    out = PROTOCOL
    hello = {"ok": True, "version": jsbsim.__version__, "trim": trim}
    if trim is not None:
        hello["trim"], hello["trim_pitch_rad"] = trim
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
        values = [n.get_double_value() for n in props]
        values[-1] -= t0
        out.write(OUT.pack(*values))


try:
    main()
except SystemExit:
    raise
except BaseException as e:  # noqa: BLE001 - whatever JSBSim throws ends the run in one line
    fail(f"{type(e).__name__}: {e}")
