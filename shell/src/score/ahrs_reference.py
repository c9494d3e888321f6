"""Reference attitude filters for `skyframe sim --score`: the `ahrs` package's EKF and
Madgwick filters run on the flight's IMU samples, so their roll/pitch can be scored against
the same ground truth as skyframe's estimator.

Input (argv[1]): CSV without header, one IMU sample per line at a fixed rate:
    t_s, p_rad_s, q_rad_s, r_rad_s, fx_m_s2, fy_m_s2, fz_m_s2
body FRD rates and specific force as `conventions.md` defines them (level at rest reads
fz = -9.80665). argv[2]: the sample rate (Hz).
Output (stdout): `version,<ahrs version>`, then one line per sample:
    t_s, ekf_roll_rad, ekf_pitch_rad, madgwick_roll_rad, madgwick_pitch_rad
"""
import sys

import numpy as np
import ahrs
from ahrs.filters import EKF, Madgwick


def roll_pitch(q):
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    return roll, pitch


def main():
    data = np.loadtxt(sys.argv[1], delimiter=",", ndmin=2)
    rate_hz = float(sys.argv[2])
    t = data[:, 0]
    gyr = data[:, 1:4]
    # ahrs takes the accelerometer as reading +g upwards at rest (0, 0, +9.81 level): the
    # opposite of the specific force convention our logs use.
    acc = -data[:, 4:7]
    ekf = EKF(gyr=gyr, acc=acc, frequency=rate_hz, frame="NED")
    madgwick = Madgwick(gyr=gyr, acc=acc, frequency=rate_hz)
    er, ep = roll_pitch(ekf.Q)
    mr, mp = roll_pitch(madgwick.Q)
    out = sys.stdout
    out.write("version,%s\n" % ahrs.__version__)
    for row in zip(t, er, ep, mr, mp):
        out.write("%.6f,%.7f,%.7f,%.7f,%.7f\n" % row)


if __name__ == "__main__":
    main()
