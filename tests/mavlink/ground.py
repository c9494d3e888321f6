"""A pymavlink ground station for tests/mavlink.rs: talks to a real `skyframe sim
--mavlink udpin:127.0.0.1:PORT`, does what a ground station does, and prints what it saw as
one JSON object. It asserts nothing: the Rust test compares what it saw with independent
sources (the scenario's home, the flight's log, the mission file).

    python3 ground.py PORT parked|auto|signed|stop [KEY_HEX]
"""

import json
import sys
import time

from pymavlink import mavutil

PORT = int(sys.argv[1])
PHASE = sys.argv[2]
KEY = bytes.fromhex(sys.argv[3]) if PHASE == "signed" and len(sys.argv) > 3 else None

mav = mavutil.mavlink
# "listen": the ground station listens (as QGC on 14550) and the vehicles send to it.
MODE = "udpin" if PHASE == "listen" else "udpout"
m = mavutil.mavlink_connection(f"{MODE}:127.0.0.1:{PORT}", source_system=255, source_component=190)


def hello():
    m.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)


def wait(kind, timeout=5.0, cond=None):
    end = time.time() + timeout
    while time.time() < end:
        msg = m.recv_match(type=kind, blocking=True, timeout=0.5)
        if msg is None:
            hello()
            continue
        if cond is None or cond(msg):
            return msg
    return None


def as_dict(msg):
    if msg is None:
        return None
    d = msg.to_dict()
    d.pop("mavpackettype", None)
    return d


def first_contact():
    end = time.time() + 20
    while time.time() < end:
        hello()
        if m.recv_match(type="HEARTBEAT", blocking=True, timeout=1.0) is not None:
            return True
    return False


def command(cmd, *params, timeout=5.0):
    p = list(params) + [0.0] * (7 - len(params))
    m.mav.command_long_send(1, 1, cmd, 0, *p)
    ack = wait("COMMAND_ACK", timeout, lambda a: a.command == cmd)
    return None if ack is None else ack.result


def param_list():
    m.mav.param_request_list_send(1, 1)
    params = {}
    count = None
    end = time.time() + 10
    while time.time() < end and (count is None or len(params) < count):
        msg = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.5)
        if msg is None:
            continue
        count = msg.param_count
        params[msg.param_index] = {"id": msg.param_id, "value": msg.param_value, "type": msg.param_type, "count": msg.param_count}
    return [params[i] for i in sorted(params)]


def param_set(name, value):
    m.mav.param_set_send(1, 1, name.encode(), value, mav.MAV_PARAM_TYPE_REAL32)
    msg = wait("PARAM_VALUE", 5, lambda p: p.param_id == name)
    return None if msg is None else msg.param_value


def param_read(name):
    m.mav.param_request_read_send(1, 1, name.encode(), -1)
    msg = wait("PARAM_VALUE", 5, lambda p: p.param_id == name)
    return None if msg is None else msg.param_value


def mission_download():
    m.mav.mission_request_list_send(1, 1, mav.MAV_MISSION_TYPE_MISSION)
    count = wait("MISSION_COUNT", 5)
    if count is None:
        return None
    items = []
    for seq in range(count.count):
        m.mav.mission_request_int_send(1, 1, seq, mav.MAV_MISSION_TYPE_MISSION)
        item = wait("MISSION_ITEM_INT", 5, lambda i, s=seq: i.seq == s)
        if item is None:
            return None
        items.append(as_dict(item))
    m.mav.mission_ack_send(1, 1, mav.MAV_MISSION_ACCEPTED, mav.MAV_MISSION_TYPE_MISSION)
    return items


def mission_download_once_home_is_known(seconds=30):
    """The mission's positions need home (the first GPS fix): ask until it is there."""
    end = time.time() + seconds
    while time.time() < end:
        items = mission_download()
        if items is not None:
            return items
        time.sleep(0.5)
    return None


def mission_upload(items):
    """The mission protocol from the ground's side: COUNT, then each item as asked."""
    m.mav.mission_count_send(1, 1, len(items), mav.MAV_MISSION_TYPE_MISSION)
    end = time.time() + 15
    while time.time() < end:
        msg = m.recv_match(type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], blocking=True, timeout=0.5)
        if msg is None:
            continue
        if msg.get_type() == "MISSION_ACK":
            return msg.type
        i = items[msg.seq]
        m.mav.mission_item_int_send(
            1, 1, msg.seq, i["frame"], i["command"], 0, 1,
            i["param1"], i["param2"], i["param3"], i["param4"], i["x"], i["y"], i["z"],
            mav.MAV_MISSION_TYPE_MISSION)
    return None


def collect(seconds):
    """Every message for `seconds`: arrival times of heartbeats, the last of each type."""
    seen = {}
    heartbeats = []
    texts = []
    end = time.time() + seconds
    next_hello = 0
    while time.time() < end:
        if time.time() > next_hello:
            hello()
            next_hello = time.time() + 1
        msg = m.recv_match(blocking=True, timeout=0.2)
        if msg is None:
            continue
        t = msg.get_type()
        if t == "HEARTBEAT":
            heartbeats.append({"t": time.time(), **as_dict(msg)})
        if t == "STATUSTEXT":
            texts.append(msg.text)
        entry = seen.setdefault(t, {"count": 0, "first_t": time.time()})
        entry["count"] += 1
        entry["last_t"] = time.time()
        entry["last"] = as_dict(msg)
    return seen, heartbeats, texts


if PHASE == "listen":
    systems = {}
    end = time.time() + 10
    while time.time() < end:
        msg = m.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
        if msg is not None:
            systems.setdefault(str(msg.get_srcSystem()), []).append(msg.get_srcComponent())
    print(json.dumps({"contact": bool(systems), "heartbeats_by_system": {k: len(v) for k, v in systems.items()}, "components": sorted({c for v in systems.values() for c in v})}))
    sys.exit(0)

out = {"contact": first_contact()}
if PHASE == "parked":
    # Let the estimator align and the streams settle.
    seen, heartbeats, texts = collect(12)
    out.update(streams=seen, heartbeats=heartbeats, statustexts=texts)
    out["autopilot_version_ack"] = command(mav.MAV_CMD_REQUEST_MESSAGE, 148)
    out["autopilot_version"] = as_dict(wait("AUTOPILOT_VERSION", 5))
    out["home_ack"] = command(mav.MAV_CMD_REQUEST_MESSAGE, 242)
    out["home"] = as_dict(wait("HOME_POSITION", 5))
    out["params"] = param_list()
    out["param_read_by_index"] = None
    m.mav.param_request_read_send(1, 1, b"", 3)
    msg = wait("PARAM_VALUE", 5, lambda p: p.param_index == 3)
    out["param_read_by_index"] = as_dict(msg)
    out["set_accepted"] = param_set("CTL_ROLL_KP", 0.75)
    out["set_rejected"] = param_set("CTL_ROLL_KP", 50.0)
    out["read_back"] = param_read("CTL_ROLL_KP")
    items = mission_download()
    out["mission"] = items
    out["upload_same"] = mission_upload(items) if items else None
    if items:
        takeoff = [dict(i) for i in items]
        takeoff[1]["command"] = mav.MAV_CMD_NAV_TAKEOFF
        out["upload_takeoff"] = mission_upload(takeoff)
        local = [dict(i) for i in items]
        local[1]["frame"] = mav.MAV_FRAME_LOCAL_NED
        out["upload_local_frame"] = mission_upload(local)
    out["unsupported_command"] = command(mav.MAV_CMD_DO_SET_SERVO, 1, 1500)
    out["arm"] = command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    out["set_mode_stabilise"] = command(mav.MAV_CMD_DO_SET_MODE, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 2)
    out["set_mode_nonsense"] = command(mav.MAV_CMD_DO_SET_MODE, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 7)
    out["interval_ack"] = command(mav.MAV_CMD_SET_MESSAGE_INTERVAL, 30, 500000)
    seen, _, _ = collect(4)
    out["attitude_after_interval"] = seen.get("ATTITUDE")
elif PHASE == "auto":
    items = mission_download_once_home_is_known()
    out["mission"] = items
    out["upload_same"] = mission_upload(items) if items else None
    reached = []
    modes = set()
    landed = set()
    top_mm = None
    end = time.time() + float(sys.argv[3]) if len(sys.argv) > 3 else time.time() + 60
    while time.time() < end:
        msg = m.recv_match(type=["MISSION_ITEM_REACHED", "HEARTBEAT", "EXTENDED_SYS_STATE", "GLOBAL_POSITION_INT"], blocking=True, timeout=0.5)
        if msg is None:
            hello()
            continue
        if msg.get_type() == "HEARTBEAT":
            modes.add(msg.custom_mode)
        elif msg.get_type() == "EXTENDED_SYS_STATE":
            landed.add(msg.landed_state)
        elif msg.get_type() == "GLOBAL_POSITION_INT":
            top_mm = msg.relative_alt if top_mm is None else max(top_mm, msg.relative_alt)
        else:
            reached.append(msg.seq)
            if items and len(reached) >= sum(1 for i in items if i["command"] == mav.MAV_CMD_NAV_WAYPOINT):
                break
    out["reached"] = reached
    out["modes"] = sorted(modes)
    out["landed_states"] = sorted(landed)
    out["highest_relative_alt_mm"] = top_mm
elif PHASE == "inflight":
    # A new mission in flight, flown; set-current; clear-all.
    items = mission_download_once_home_is_known()
    out["mission"] = items
    # In the air on the first mission: its first waypoint reached.
    first_seq = next(i["seq"] for i in items if i["command"] == mav.MAV_CMD_NAV_WAYPOINT)
    out["first_reached"] = as_dict(wait("MISSION_ITEM_REACHED", 60, lambda r: r.seq == first_seq))
    # The new mission: the first's last two waypoints, 10 m higher, and the loiter at the last.
    wps = [dict(i) for i in items if i["command"] == mav.MAV_CMD_NAV_WAYPOINT][2:]
    for w in wps:
        w["z"] += 10
    speed = dict(next(i for i in items if i["command"] == mav.MAV_CMD_DO_CHANGE_SPEED))
    loiter = dict(items[-1])
    loiter.update(x=wps[-1]["x"], y=wps[-1]["y"], z=wps[-1]["z"])
    new = [speed] + wps + [loiter]
    for seq, i in enumerate(new):
        i["seq"] = seq
    out["uploaded"] = new
    out["upload_new"] = mission_upload(new)
    out["downloaded"] = mission_download()
    reached = []
    currents = []
    end = time.time() + 60
    want = [i["seq"] for i in new if i["command"] == mav.MAV_CMD_NAV_WAYPOINT]
    while time.time() < end and len(reached) < len(want):
        msg = m.recv_match(type=["MISSION_ITEM_REACHED", "MISSION_CURRENT"], blocking=True, timeout=0.5)
        if msg is None:
            hello()
        elif msg.get_type() == "MISSION_CURRENT":
            currents.append(msg.seq)
        else:
            reached.append(msg.seq)
    out["reached"] = reached
    out["currents_while_flying"] = currents
    # Back to the new mission's first waypoint.
    m.mav.mission_set_current_send(1, 1, want[0])
    cur = wait("MISSION_CURRENT", 10, lambda c: c.seq == want[0])
    out["set_current"] = as_dict(cur)
    m.mav.mission_clear_all_send(1, 1, mav.MAV_MISSION_TYPE_MISSION)
    ack = wait("MISSION_ACK", 10)
    out["clear_all"] = None if ack is None else ack.type
    out["after_clear"] = mission_download()
    m.mav.mission_set_current_send(1, 1, 1)
    out["set_current_without_mission"] = as_dict(wait("MISSION_CURRENT", 5))
elif PHASE == "signed":
    if KEY is not None:
        # Receive signed telemetry; send nothing signed yet.
        m.setup_signing(KEY, sign_outgoing=False)
    out["before"] = param_read("CTL_ROLL_KP")
    m.mav.param_set_send(1, 1, b"CTL_ROLL_KP", 0.6, mav.MAV_PARAM_TYPE_REAL32)
    time.sleep(1.5)
    out["after_unsigned"] = param_read("CTL_ROLL_KP")
    m.setup_signing(KEY, sign_outgoing=True)
    out["signed_set"] = param_set("CTL_ROLL_KP", 0.65)
    out["after_signed"] = param_read("CTL_ROLL_KP")
    hb = wait("HEARTBEAT", 5)
    out["heartbeat_signed"] = None if hb is None else bool(hb.get_signed())
elif PHASE == "stop":
    # Wait for the stuck task, then ask the autopilot to shut down.
    time.sleep(float(sys.argv[3]) if len(sys.argv) > 3 else 0)
    out["stop_ack"] = command(mav.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 2)
    out["stop_sent_at"] = time.time()
print(json.dumps(out))
