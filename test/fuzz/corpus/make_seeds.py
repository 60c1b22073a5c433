#!/usr/bin/env python3
"""Writes the generated seed inputs of the libFuzzer targets (docs/fuzzing.md)
into test/fuzz/corpus/<target>/. Deterministic; rerun after a format change.
Hand-written seeds (INI, TOML, logs) live beside them and are not touched."""
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", "..", ".."))


def put(target, name, data):
    d = os.path.join(HERE, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


# --- SCIP 2.0 (fuzz_urg_scip2): what a URG-04LX sends in one session -------
def ssum(text):
    return chr((sum(text.encode()) & 0x3F) + 0x30)


def status(code):
    return code + ssum(code) + "\n"


def field(key, text):
    line = key + ":" + text
    return line + ";" + ssum(line) + "\n"


def enc(v, n):
    return "".join(chr(((v >> (6 * (n - 1 - i))) & 0x3F) + 0x30) for i in range(n))


def data_lines(chars):
    out = ""
    for i in range(0, len(chars), 64):
        part = chars[i:i + 64]
        out += part + ssum(part) + "\n"
    return out


FIRST, LAST, CLUSTER = 44, 725, 10
POINTS = (LAST - FIRST) // CLUSTER + 1


def scan_body(stamp_ms, ranges):
    ts = enc(stamp_ms, 4)
    return ts + ssum(ts) + "\n" + data_lines("".join(enc(r, 3) for r in ranges)) + "\n"


def pp():
    return ("PP\n" + status("00") + field("MODL", "URG-04LX(Hokuyo Automatic Co.,Ltd.)") +
            field("DMIN", "20") + field("DMAX", "5600") + field("ARES", "1024") + field("AMIN", "44") +
            field("AMAX", "725") + field("AFRT", "384") + field("SCAN", "600") + "\n")


def vv():
    return ("VV\n" + status("00") + field("VEND", "Hokuyo Automatic Co.,Ltd.") + field("PROD", "URG-04LX") +
            field("FIRM", "3.3.00") + field("PROT", "SCIP 2.0") + field("SERI", "H0904650") + "\n")


def ii():
    return ("II\n" + status("00") + field("MODL", "URG-04LX") + field("LASR", "OFF") +
            field("SCSP", "600[rpm]") + field("MESM", "Measuring by Normal Mode") +
            field("SBPS", "USB only") + field("TIME", "00A5A3") + field("STAT", "Sensor works well.") + "\n")


def ranges(k):
    # valid ranges, error codes (0..19) and one beyond DMAX
    return [(0 if i % 17 == 0 else 7 if i % 23 == 0 else 6000 if i % 31 == 0 else 300 + 40 * i + k)
            for i in range(POINTS)]


def session(stamps, chunk=0):
    md = "MD%04d%04d%02d%d%02d" % (FIRST, LAST, CLUSTER, 0, 0)
    gd = "GD%04d%04d%02d" % (FIRST, LAST, CLUSTER)
    s = pp() + vv() + ii() + "BM\n" + status("00") + "\n"
    s += gd + "\n" + status("00") + scan_body(stamps[0], ranges(0))
    s += md + "\n" + status("00") + "\n"
    for k, t in enumerate(stamps[1:]):
        s += md[:13] + "00\n" + status("99") + scan_body(t, ranges(k + 1))
    s += "QT\n" + status("00") + "\n"
    return bytes([chunk | ((len(stamps) - 2) << 6)]) + s.encode()


put("fuzz_urg_scip2", "session", session([1000, 1100, 1200, 1300]))
put("fuzz_urg_scip2", "session_wrap_chunk7", session([2 ** 24 - 150, 2 ** 24 - 50, 50, 150], chunk=7))
put("fuzz_urg_scip2", "session_backwards_chunk1", session([5000, 5100, 100, 5300], chunk=1))
put("fuzz_urg_scip2", "pp_only", bytes([0]) + pp().encode())
put("fuzz_urg_scip2", "status_error", bytes([0]) + ("PP\n" + status("0E") + "\n").encode())


# --- CANopen / CiA 402 (fuzz_cia402): 12-byte records ----------------------
HB, SDO, TPDO, EMCY, SDO_OTHER, RAW, NMT, EXT = range(8)


def rec(kind, dlc, data=b"", action=0, dt_ms=1, r3=0, flags=0):
    data = (data + bytes(8))[:8]
    return bytes([kind | flags, (action << 4) | dlc, dt_ms, r3]) + data


def upload(index, sub, value, size):
    cmd = 0x43 | ((4 - size) << 2)
    return struct.pack("<BHBI", cmd, index, sub, value)


def ack(index, sub):
    return struct.pack("<BHBI", 0x60, index, sub, 0)


def tpdo(sw, vel):
    return struct.pack("<Hi", sw, vel)


bringup = (rec(HB, 1, b"\x00") +                               # boot-up
           rec(SDO, 8, upload(0x1018, 1, 0x0000019A, 4)) +     # vendor id
           rec(SDO, 8, upload(0x1018, 2, 0x00001234, 4)) +     # product code
           rec(SDO, 8, ack(0x1017, 0)) +                       # heartbeat producer
           rec(SDO, 8, ack(0x6060, 0)) +                       # mode of operation
           rec(SDO, 8, upload(0x6061, 0, 3, 1)) +              # mode display
           rec(SDO, 8, upload(0x6041, 0, 0x0240, 2)) +         # statusword
           rec(HB, 1, b"\x05", action=1))                      # operational, goal ENABLED
run = b""
for sw in (0x0240, 0x0221, 0x0233, 0x0237, 0x0237):
    run += rec(TPDO, 6, tpdo(sw, 100), dt_ms=10)
run += rec(TPDO, 6, tpdo(0x0237, 500), action=4, dt_ms=10) + rec(HB, 1, b"\x05", dt_ms=50)
put("fuzz_cia402", "bringup_run", bringup + run)
put("fuzz_cia402", "emcy_fault_reset",
    bringup + run + rec(EMCY, 8, struct.pack("<HB5s", 0x2310, 0x03, b"\x01\x02\x03\x04\x05")) +
    rec(TPDO, 6, tpdo(0x0208, 0), dt_ms=10) + rec(TPDO, 6, tpdo(0x0208, 0), action=5, dt_ms=10) +
    rec(TPDO, 6, tpdo(0x0240, 0), dt_ms=10) + rec(EMCY, 8, bytes(8)))
put("fuzz_cia402", "sdo_abort", bringup[:12 * 2] + rec(SDO, 8, struct.pack("<BHBI", 0x80, 0x1018, 2, 0x06020000)))
put("fuzz_cia402", "user_sdo",
    bringup + run + rec(TPDO, 6, tpdo(0x0237, 0), action=6, r3=0) +
    rec(SDO, 8, upload(0x0000, 0, 7, 2)) + rec(SDO, 8, struct.pack("<BHBI", 0x41, 0x2000, 0, 100)))
put("fuzz_cia402", "heartbeat_lost", bringup + run + rec(SDO_OTHER, 8, ack(0x1017, 0), dt_ms=255) +
    rec(RAW | (7 << 3), 8, bytes(8), r3=0x03, dt_ms=255) + rec(NMT, 2, b"\x81\x03") + rec(EXT, 8, bytes(8)))


# --- map message (fuzz_map_msg): the target XORs onto its own valid
# messages; byte 0 picks one of them, so these select each template -------
for t in range(4):
    put("fuzz_map_msg", "template%d" % t, bytes([t]))
    put("fuzz_map_msg", "template%d_raw" % t, bytes([t | 0x80, 0, 0, 0, 0]))


# --- replay readers (fuzz_replay_data): byte 0 picks the reader -----------
LOG = """# robot 1
V 0.0 0.1 0.0
O 0.05 0.01 0.0 0.001
Z 0.1 11 1.5 0.2
Z 0.1 -1 2.25 -0.4
R 0.2 2 3.0 1.0
V 0.3 0.2 -0.1
"""
TRUTH = "# t x y theta\n0.0 0 0 0\n0.1 0.01 0 0.01\n0.2 0.02 0.001 3.2\n"
LMS = "# id x y\n11 1.0 2.0\n12 -3.5 0.25 0.01 0.01\n"
put("fuzz_replay_data", "log", b"\x00" + LOG.encode())
put("fuzz_replay_data", "truth_path", b"\x01" + TRUTH.encode())
put("fuzz_replay_data", "truth_landmarks", b"\x02" + LMS.encode())
MR = ["1 5\n2 14\n6 27\n7 41\n",                          # Barcodes.dat subject barcode
      "6 1.5 2.5 0.01 0.01\n7 -1.0 3.0 0.01 0.01\n",     # Landmark_Groundtruth.dat
      "1248272262.931 0.0 0.0\n1248272262.951 0.1 -0.2\n",
      "1248272263.000 27 2.5 0.1\n1248272263.100 14 1.2 -0.3\n1248272263.2 99 1.0 0.0\n",
      "1248272262.900 0 0 0\n1248272263.0 0.1 0 0.01\n",
      "1248272262.5 0.0 0.0\n",
      "1248272263.0 5 1.0 0.0\n"]
put("fuzz_replay_data", "mrclam", b"\x03" + "\x01".join(MR).encode())
LD = [LOG, TRUTH, "V 0 0 0\nR 1 1 2.0 0.5\n", LMS, "# t0\n1248272262.9\n"]
put("fuzz_replay_data", "logdir", b"\x04" + "\x01".join(LD).encode())


# --- INI loaders: the shipped files plus small hand-written ones ----------
def copy(target, name, path):
    with open(os.path.join(ROOT, path), "rb") as f:
        put(target, name, f.read())


copy("fuzz_robot_config", "robot.ini", "firmware/port/linux/robot.ini")
put("fuzz_robot_config", "small.ini",
    "[robot]\nid = 1\nfleet_size = 3\nstatus_period_s = 0\n[slam]\nrange_var_m2 = 0.0025\ngate_chi2 = 9.21\n"
    "[link]\npeers = 10.0.0.1, 10.0.0.2\ninsecure = true\n")
put("fuzz_robot_config", "number.ini", "1e-5")
copy("fuzz_replay_config", "mrclam6.ini", "host/replay/mrclam6.ini")
put("fuzz_replay_config", "small.ini",
    "[filter]\ntype = ekf\nparticles = 50\n[odometry]\nscale_v = 0.9\n[merge]\nwindow_s = 0.25\n"
    "[robot.2]\nfilter = fastslam1\nscale_w = 1.1\n[slam]\nbearing_var_rad2 = 0.001\n")
copy("fuzz_scenario", "paper.toml", "sim/scenarios/paper.toml")
put("fuzz_scenario", "small.toml",
    'name = "tiny"\nduration_s = 5.0\n[world]\narena = [[0, 0], [4, 0], [4, 4], [0, 4]]\n'
    'landmarks = [{pos = [1, 1], signature = 1}]\n[[robots]]\nname = "a"\nstart = [1, 2, 0]\n'
    '[[robots]]\nname = "b"\nstart = [3, 2, 180]\nfilter = "ekf"\n')
