#!/usr/bin/env python3
"""Real labelled frames for `skyframe-horizon bench --real`: the Horizon-UAV set.

490 frames (480x480 JPEG) of front-facing UAV video with sky/land masks and a straight-line
label each, MIT licence, (c) 2021 Novelio Putra Indarto
(https://github.com/NovelioPI/horizon-detection-for-uav; the `dataset-slope` variant, mirrored
with its licence note in https://github.com/JuroUhlar/etdh-horizon-detection under
data/horizon_uav_dataset). Not shipped in this repository (105 MB as PNG).

    git clone --depth 1 https://github.com/JuroUhlar/etdh-horizon-detection /tmp/etdh
    python3 tools/horizon/horizon_uav_set.py /tmp/etdh/data/horizon_uav_dataset /tmp/horizon-uav
    skyframe-horizon bench --real /tmp/horizon-uav --only horizon-uav

Writes frame_NNNNNN.png (in label.csv order), camera.toml and truth.csv. The camera is an
assumption, as the set has no calibration: 60 degrees horizontal field of view, principal point
at the centre (the issue's reading of these frames). A label is `y = slope*x + offset*480` in
pixel coordinates (least squares on the mask boundary); in the conventions' terms roll =
atan(-slope), and the pitch follows from the line's height at the principal point. Every frame
shows the horizon (visible = 1). Needs opencv-python-headless (JPEG decoding).
"""
import csv
import math
import os
import sys

import cv2


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: horizon_uav_set.py DATASET_DIR (with images/ and label.csv) OUT_DIR")
    source, out = sys.argv[1], sys.argv[2]
    try:
        with open(os.path.join(source, "label.csv"), newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        sys.exit(f"horizon_uav_set: {e}")
    os.makedirs(out, exist_ok=True)
    width = height = 480
    fx = fy = (width / 2) / math.tan(math.radians(30))
    cx, cy = (width - 1) / 2, (height - 1) / 2
    with open(os.path.join(out, "camera.toml"), "w") as f:
        f.write(f"width = {width}\nheight = {height}\nfx = {fx}\nfy = {fy}\ncx = {cx}\ncy = {cy}\nk1 = 0.0\nk2 = 0.0\n")
    truth = ["frame,roll_deg,pitch_deg,visible"]
    for i, row in enumerate(rows):
        path = os.path.join(source, "images", row["filename"])
        image = cv2.imread(path, cv2.IMREAD_COLOR)
        if image is None or image.shape[:2] != (height, width):
            sys.exit(f"horizon_uav_set: {path}: not a {width}x{height} image")
        cv2.imwrite(os.path.join(out, f"frame_{i:06d}.png"), image)
        slope, offset_px = float(row["slope"]), float(row["offset"]) * height
        roll = math.atan2(-slope, 1.0)
        pitch = math.atan(math.cos(roll) * (slope * cx + offset_px - cy) / fy)
        truth.append(f"{i},{math.degrees(roll):.4f},{math.degrees(pitch):.4f},1")
    with open(os.path.join(out, "truth.csv"), "w") as f:
        f.write("\n".join(truth) + "\n")
    print(f"{len(rows)} frames in {out}")


if __name__ == "__main__":
    main()
